//! The devices on the functional bus (thesis §4.2.1): the camera, the STM32
//! (with the PID of §4.2.2) and the motors. Each has a functional side (its
//! registers and what a write does) and a power side (its states, each with a
//! current and a delay, as MESSY's sensors).

pub mod stm32;

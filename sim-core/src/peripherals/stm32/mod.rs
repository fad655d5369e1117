//! The STM32 of the Crazyflie as the thesis models it (§4.2.1, Table 4.3):
//! it runs the flight controller ([`pid`]) on sensor data from the world and
//! drives the motors.

pub mod pid;

//! The firmware's console (semihosting output and the STM32's prints),
//! written to `console.log` and, if asked, echoed on stdout; and the
//! progress line shown on a terminal.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::peripherals::stm32::crtp::console::{self as crtp_console, ConsoleTap};
use crate::power::PowerNetwork;
use crate::units::Picos;

struct Inner {
    file: Option<BufWriter<File>>,
    echo: bool,
    /// Everything printed, for the summary and tests.
    text: Vec<u8>,
    /// The CRTP link's console (port 0), when one is served.
    tap: Option<ConsoleTap>,
}

/// A shared console: the ISS's semihosting writes into it through
/// [`Console::writer`], the devices through [`Console::write_str`].
#[derive(Clone)]
pub struct Console {
    inner: Arc<Mutex<Inner>>,
}

/// A `Write` handle on the console for the ISS.
pub struct ConsoleWriter {
    inner: Arc<Mutex<Inner>>,
}

impl Console {
    pub fn create(dir: Option<&Path>, echo: bool) -> io::Result<Console> {
        let file = match dir {
            Some(dir) => {
                std::fs::create_dir_all(dir)?;
                let path = dir.join("console.log");
                Some(BufWriter::new(File::create(&path).map_err(|e| {
                    io::Error::new(e.kind(), format!("cannot create {}: {e}", path.display()))
                })?))
            }
            None => None,
        };
        Ok(Console {
            inner: Arc::new(Mutex::new(Inner {
                file,
                echo,
                text: Vec::new(),
                tap: None,
            })),
        })
    }

    pub fn writer(&self) -> ConsoleWriter {
        ConsoleWriter {
            inner: Arc::clone(&self.inner),
        }
    }

    /// From now on everything printed is also appended to `tap` (the CRTP
    /// console's unsent text).
    pub fn set_tap(&self, tap: ConsoleTap) {
        self.inner.lock().expect("console lock").tap = Some(tap);
    }

    pub fn write_str(&self, s: &str) {
        // A console that cannot be written is reported at flush.
        let _ = self.writer().write_all(s.as_bytes());
    }

    /// Everything printed so far.
    pub fn text(&self) -> String {
        let inner = self.inner.lock().expect("console lock");
        String::from_utf8_lossy(&inner.text).into_owned()
    }

    pub fn flush(&self) -> io::Result<()> {
        let mut inner = self.inner.lock().expect("console lock");
        if inner.echo {
            io::stdout().flush()?;
        }
        match &mut inner.file {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

impl Write for ConsoleWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let mut inner = self.inner.lock().expect("console lock");
        inner.text.extend_from_slice(buf);
        if let Some(tap) = &inner.tap {
            crtp_console::append(tap, buf);
        }
        if inner.echo {
            let mut out = io::stdout().lock();
            out.write_all(buf)?;
            if buf.contains(&b'\n') {
                out.flush()?;
            }
        }
        if let Some(f) = &mut inner.file {
            f.write_all(buf)?;
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        let mut inner = self.inner.lock().expect("console lock");
        match &mut inner.file {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

/// The progress line: simulated time, real-time factor and SOC, on a
/// terminal only (indicatif draws nothing when stderr is not a terminal).
pub struct Progress {
    bar: Option<ProgressBar>,
    start: Instant,
    next_update: Picos,
}

impl Progress {
    pub fn new(enabled: bool) -> Progress {
        let bar = enabled.then(|| {
            let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr_with_hz(4));
            bar.set_style(ProgressStyle::with_template("{spinner} {msg}").expect("valid template"));
            bar
        });
        Progress {
            bar,
            start: Instant::now(),
            next_update: Picos::ZERO,
        }
    }

    pub fn update(&mut self, now: Picos, power: &PowerNetwork) {
        let Some(bar) = &self.bar else { return };
        if now < self.next_update {
            return;
        }
        // Refresh every 100 ms of simulated time; the draw target limits the
        // terminal updates further.
        self.next_update = now + Picos::from_ms(100);
        let wall = self.start.elapsed().as_secs_f64().max(1e-9);
        bar.set_message(format!(
            "simulated {:.1} s | {:.0}x real time | SOC {:.1} %",
            now.as_secs_f64(),
            now.as_secs_f64() / wall,
            power.battery().soc() * 100.0
        ));
        bar.tick();
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

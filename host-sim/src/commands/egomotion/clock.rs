//! When each frame of a sequence was taken.

/// Frame times of a sequence at a constant rate: frame `k` is taken `k / fps` seconds after
/// frame 0, rounded to the microsecond (the resolution of MAVLink's timestamps and of gyro logs).
///
/// ```
/// use host_sim::egomotion::FrameClock;
/// let clock = FrameClock::new(30.0);
/// assert_eq!((clock.time_us(0), clock.time_us(1), clock.time_us(3)), (0, 33_333, 100_000));
/// assert_eq!(clock.interval_us(2), 33_334);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameClock {
    fps: f64,
}

impl FrameClock {
    /// Frames per second to use when the input gives none.
    pub const DEFAULT_FPS: f64 = 30.0;

    /// A clock at `fps` frames per second (positive and finite; the command line checks).
    pub fn new(fps: f64) -> Self {
        Self { fps }
    }

    /// Frames per second.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// Time of frame `k`, microseconds after frame 0.
    pub fn time_us(&self, k: usize) -> u64 {
        (k as f64 * 1e6 / self.fps).round() as u64
    }

    /// Microseconds between frame `k - 1` and frame `k` (`k >= 1`).
    pub fn interval_us(&self, k: usize) -> u32 {
        let interval = self.time_us(k) - self.time_us(k.saturating_sub(1));
        u32::try_from(interval).unwrap_or(u32::MAX)
    }
}

/// Paces a replay in real time: frame `k` is let through `k / rate` seconds after the pacer
/// started, so a slow frame is caught up on and never makes the stream run slow.
///
/// ```
/// use host_sim::egomotion::Pacer;
/// let pacer = Pacer::new(200.0);
/// let start = std::time::Instant::now();
/// pacer.wait(2);
/// assert!(start.elapsed().as_secs_f64() >= 0.0099);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Pacer {
    start: std::time::Instant,
    rate: f64,
}

impl Pacer {
    /// A pacer at `rate` frames per second (positive and finite; the command line checks).
    pub fn new(rate: f64) -> Self {
        Self {
            start: std::time::Instant::now(),
            rate,
        }
    }

    /// Sleeps until frame `k` is due.
    pub fn wait(&self, k: usize) {
        let due = self.start + std::time::Duration::from_secs_f64(k as f64 / self.rate);
        let now = std::time::Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
    }
}

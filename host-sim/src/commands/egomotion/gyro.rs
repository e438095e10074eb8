//! Gyro logs: body rates sampled over time, integrated over each frame interval.
//!
//! A log is a CSV file with the columns `t_us,gx,gy,gz`: time in microseconds on the frames'
//! clock (frame 0 at 0, see [`super::FrameClock`]), then the body rates in rad/s about the
//! sensor axes of PX4's optical-flow convention (X to the top of the image, Y to its right, Z
//! along the optical axis; see `kestrel::ego::Rotation`). Rates are taken to vary linearly
//! between samples, so a constant rate is integrated exactly however it is sampled.
//!
//! Times must be finite and increasing. Rates are read as they are: NaN, infinities and absurd
//! values are passed on for the library to reject per frame (it reports quality 0), so one bad
//! sample spoils only the frames it falls in.

use std::path::Path;

use crate::io::csv::{parse_finite, parse_number, read_text, Table};
use crate::io::InputError;

/// The columns a gyro log starts with.
pub const GYRO_COLUMNS: [&str; 4] = ["t_us", "gx", "gy", "gz"];

/// One gyro reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroSample {
    /// Time, microseconds on the frames' clock.
    pub t_us: f64,
    /// Body rates about sensor X, Y and Z, rad/s.
    pub rates: [f64; 3],
}

/// A gyro log: samples in increasing time order.
#[derive(Debug, Clone, PartialEq)]
pub struct GyroLog {
    samples: Vec<GyroSample>,
}

impl GyroLog {
    /// Reads the gyro log at `path`.
    pub fn read(path: &Path) -> Result<Self, InputError> {
        Self::parse(&read_text(path)?, &path.display().to_string())
    }

    /// Parses the text of a gyro log named `input` in messages.
    ///
    /// ```
    /// use host_sim::egomotion::GyroLog;
    /// let log = GyroLog::parse("t_us,gx,gy,gz\n0,1,0,0\n1000,1,0,0\n", "g.csv").unwrap();
    /// assert_eq!(log.integrate(250.0, 750.0), Some([0.0005, 0.0, 0.0]));
    /// let error = GyroLog::parse("t_us,gx,gy,gz\n0,1,0,0\n0,1,x,0\n", "g.csv").unwrap_err();
    /// assert_eq!(error.to_string(), "g.csv: line 3, column 3 (gy): \"x\" is not a number");
    /// ```
    pub fn parse(text: &str, input: &str) -> Result<Self, InputError> {
        let table = Table::read(text, input, &GYRO_COLUMNS)?;
        let mut samples: Vec<GyroSample> = Vec::with_capacity(table.records.len());
        for record in &table.records {
            let t_us = table.value(record, 0, parse_finite)?;
            let mut rates = [0.0; 3];
            for (axis, rate) in rates.iter_mut().enumerate() {
                *rate = table.value(record, axis + 1, parse_number)?;
            }
            if let Some(last) = samples.last() {
                if t_us <= last.t_us {
                    let problem = format!(
                        "times must increase, but {t_us} follows {} on the line before",
                        last.t_us
                    );
                    return Err(table.cell_error(record, 0, problem));
                }
            }
            samples.push(GyroSample { t_us, rates });
        }
        if samples.is_empty() {
            return Err(InputError::new(input, "no gyro samples after the header"));
        }
        Ok(Self { samples })
    }

    /// The samples, in time order.
    pub fn samples(&self) -> &[GyroSample] {
        &self.samples
    }

    /// The rotation vector (rad, sensor axes): the rates integrated from `t0_us` to `t1_us`.
    /// `None` unless the log covers the whole interval (a sample at or before `t0_us` and one
    /// at or after `t1_us`).
    pub fn integrate(&self, t0_us: f64, t1_us: f64) -> Option<[f64; 3]> {
        let (first, last) = (self.samples.first()?, self.samples.last()?);
        if first.t_us > t0_us || last.t_us < t1_us || t1_us < t0_us {
            return None;
        }
        let mut angle = [0.0; 3];
        for pair in self.samples.windows(2) {
            let (a, b) = (&pair[0], &pair[1]);
            let (from, to) = (a.t_us.max(t0_us), b.t_us.min(t1_us));
            if from >= to {
                continue;
            }
            let (start, end) = (rates_at(a, b, from), rates_at(a, b, to));
            for axis in 0..3 {
                angle[axis] += (to - from) * 1e-6 * (start[axis] + end[axis]) / 2.0;
            }
        }
        Some(angle)
    }
}

/// The rates at `t` between samples `a` and `b`, linearly interpolated. At a sample's own time
/// its value is used as is, so a NaN in the neighbouring sample does not leak in.
fn rates_at(a: &GyroSample, b: &GyroSample, t: f64) -> [f64; 3] {
    if t == a.t_us {
        return a.rates;
    }
    if t == b.t_us {
        return b.rates;
    }
    let w = (t - a.t_us) / (b.t_us - a.t_us);
    std::array::from_fn(|axis| a.rates[axis] + w * (b.rates[axis] - a.rates[axis]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(text: &str) -> GyroLog {
        GyroLog::parse(text, "g.csv").unwrap()
    }

    #[test]
    fn a_linear_ramp_is_integrated_exactly() {
        // gz rises by 1 rad/s per millisecond: from 1 ms to 3 ms its mean is 2 rad/s.
        let ramp = log("t_us,gx,gy,gz\n0,0,0,0\n2000,0,0,2\n4000,0,0,4\n");
        let [_, _, z] = ramp.integrate(1000.0, 3000.0).unwrap();
        assert!((z - 0.004).abs() < 1e-12, "{z}");
    }

    #[test]
    fn intervals_outside_the_log_have_no_reading() {
        let short = log("t_us,gx,gy,gz\n100,1,1,1\n200,1,1,1\n");
        assert_eq!(short.integrate(0.0, 150.0), None);
        assert_eq!(short.integrate(150.0, 250.0), None);
        assert!(short.integrate(100.0, 200.0).is_some());
    }

    #[test]
    fn a_nan_spoils_only_the_intervals_it_is_in() {
        let spoiled = log("t_us,gx,gy,gz\n0,1,0,0\n1000,NaN,0,0\n2000,1,0,0\n3000,1,0,0\n");
        assert!(spoiled.integrate(500.0, 1500.0).unwrap()[0].is_nan());
        assert_eq!(spoiled.integrate(2000.0, 3000.0).unwrap()[0], 0.001);
    }

    #[test]
    fn times_must_increase_and_samples_exist() {
        let error = GyroLog::parse("t_us,gx,gy,gz\n5,0,0,0\n5,0,0,0\n", "g.csv").unwrap_err();
        assert_eq!(
            error.to_string(),
            "g.csv: line 3, column 1 (t_us): times must increase, but 5 follows 5 on the line before"
        );
        let nan_time = GyroLog::parse("t_us,gx,gy,gz\nnan,0,0,0\n", "g.csv").unwrap_err();
        assert!(nan_time.to_string().contains("column 1 (t_us)"));
        let empty = GyroLog::parse("t_us,gx,gy,gz\n", "g.csv").unwrap_err();
        assert_eq!(empty.to_string(), "g.csv: no gyro samples after the header");
    }
}

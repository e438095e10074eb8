//! When a frame's rows see the scene: the exposure time and the rolling shutter's readout.
//!
//! Time is counted in frame intervals from frame 0. Frame `k`'s reference instant is `t = k`,
//! the middle of its first row's exposure; sensor row `r` of `R` is read `r / R` of the
//! readout time after the first, and every row integrates the scene over the exposure time
//! centred on its own instant.

/// Largest image motion between two instants at which an exposure is sampled, px: finer than
/// the 2 x 2 area sampling of a pixel, so that a blur shows no steps.
const MAX_STEP_PX: f64 = 0.5;
/// Most instants an exposure is sampled at.
const MAX_SAMPLES: f64 = 64.0;

/// The timing of a frame's exposure, in frame intervals.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Shutter {
    /// How long each row integrates the scene (0: an instant).
    pub exposure: f64,
    /// How long after the first row the sensor reads the last (0: a global shutter).
    pub readout: f64,
}

impl Shutter {
    /// The instant sensor row `row` of `rows` of frame `k` is read: the middle of its exposure.
    ///
    /// ```
    /// use host_sim::synth::Shutter;
    /// let rolling = Shutter { exposure: 0.0, readout: 0.5 };
    /// assert_eq!(rolling.row_instant(3, 0, 100), 3.0);
    /// assert_eq!(rolling.row_instant(3, 50, 100), 3.25);
    /// ```
    pub fn row_instant(&self, k: usize, row: usize, rows: usize) -> f64 {
        k as f64 + self.readout * (row as f64 / rows as f64)
    }

    /// The instants, relative to a row's, at which its exposure is sampled: the middles of
    /// equal parts of the exposure, as many as keep the image's `travel` over the exposure
    /// (px) to half a pixel between two of them; only 0 for an instant exposure.
    ///
    /// ```
    /// use host_sim::synth::Shutter;
    /// let blur = Shutter { exposure: 0.5, readout: 0.0 };
    /// assert_eq!(blur.exposure_offsets(1.0), [-0.125, 0.125]);
    /// assert_eq!(Shutter::default().exposure_offsets(10.0), [0.0]);
    /// ```
    pub fn exposure_offsets(&self, travel: f64) -> Vec<f64> {
        if self.exposure == 0.0 {
            return vec![0.0];
        }
        let samples = (travel / MAX_STEP_PX).ceil().clamp(1.0, MAX_SAMPLES) as usize;
        (0..samples)
            .map(|s| self.exposure * ((s as f64 + 0.5) / samples as f64 - 0.5))
            .collect()
    }
}

//! Refused settings and buffers: one type for every constructor and settings check.

/// A setting or a caller's buffer that was refused: which one, and what it must be.
///
/// Every constructor and settings check of the library returns it (the LK, detector, grid,
/// dense, motion, outline, camera and RANSAC settings, [`Tracker::new`](crate::track::Tracker::new),
/// [`FlowSensor::new`](crate::sensor::FlowSensor::new), [`Pyramid::build`](crate::pyramid::Pyramid::build)),
/// and so does every function that takes a buffer the caller sizes by one of the library's
/// `const fn`s (storage, scratch, nodes, masks): such a buffer is set up once, like a setting.
/// What can go wrong with a frame or a call's inputs is each module's own error instead
/// ([`TrackerError`](crate::track::TrackerError), [`LkError`](crate::lk::LkError),
/// [`DenseError`](crate::dense::DenseError), ...), which wraps a `ConfigError` as `Config`
/// where a call also takes such a buffer.
///
/// [`ConfigError::field`] names the setting as the caller writes it, from the value passed:
/// `"max_tracks"`, `"lk.window"` (a tracker's LK window), `"buffers.storage"` (a tracker's
/// storage), `"camera.focal_x"` (a flow sensor's camera). [`ConfigError::bound`] says what it
/// must be, with the actual numbers; `Display` writes both as one sentence.
///
/// ```
/// use kestrel::track::{tracker_storage_len, Refill, Tracker, TrackerBuffers, TrackerConfig};
/// use kestrel::{Bound, ConfigError};
/// let buffers = || TrackerBuffers {
///     storage: &mut [],
///     lk_scratch: &mut [],
///     detect_scratch: &mut [],
///     candidates: &mut [],
/// };
/// let config = TrackerConfig { max_tracks: 0, ..TrackerConfig::default() };
/// let refused = Tracker::<4>::new(config, 160, 120, buffers()).unwrap_err();
/// assert_eq!(refused, ConfigError { field: "max_tracks", bound: Bound::Range { min: 1, max: 4 } });
/// assert_eq!(refused.to_string(), "max_tracks must be 1 to 4");
/// // A nested setting by its path, a buffer by its field and the length it needs.
/// let refill = Refill { below: 4, ..Refill::default() };
/// let mut config = TrackerConfig { max_tracks: 4, refill, ..TrackerConfig::default() };
/// config.lk.window = 64;
/// let refused = Tracker::<4>::new(config, 160, 120, buffers()).unwrap_err();
/// assert_eq!(refused.to_string(), "lk.window must be odd, 3 to 63");
/// config.lk.window = 21;
/// let refused = Tracker::<4>::new(config, 160, 120, buffers()).unwrap_err();
/// let needed = tracker_storage_len(160, 120, config.pyramid_levels());
/// assert_eq!(refused, ConfigError { field: "buffers.storage", bound: Bound::MinLen(needed) });
/// assert_eq!(refused.to_string(), "buffers.storage must hold at least 13080 elements");
/// ```
#[derive(Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ConfigError {
    /// The setting or buffer, as the caller writes it: a field name, or a path of field names
    /// from the value passed (`"lk.window"`, `"buffers.storage"`).
    pub field: &'static str,
    /// What it must be.
    pub bound: Bound,
}

/// What a setting must be, or how long a buffer must be: the rule a [`ConfigError`] names.
///
/// Numbers in a bound are whole numbers whatever the setting's type: a floating-point setting
/// is bounded by the kind of number it must be ([`Bound::FiniteNonNegative`]) or by whole
/// limits ([`Bound::Range`] of 1 to 100,000 for a focal length).
///
/// ```
/// use kestrel::lk::{LkParams, LucasKanade};
/// use kestrel::Bound;
/// let even = LkParams { window: 20, ..LkParams::default() };
/// let refused = LucasKanade::new(even).unwrap_err();
/// assert_eq!(refused.bound, Bound::OddRange { min: 3, max: 63 });
/// assert_eq!(refused.bound.to_string(), "must be odd, 3 to 63");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Bound {
    /// From `min` to `max`, both included.
    Range {
        /// The least value accepted.
        min: u32,
        /// The largest value accepted.
        max: u32,
    },
    /// An odd number from `min` to `max`, both included (a window or block side).
    OddRange {
        /// The least value accepted.
        min: u32,
        /// The largest value accepted.
        max: u32,
    },
    /// At least this.
    AtLeast(u32),
    /// At most this (and not NaN).
    AtMost(u32),
    /// A number >= 0: NaN and negative numbers are refused, infinity is accepted (a gate that
    /// infinity turns off).
    NonNegative,
    /// A finite number >= 0.
    FiniteNonNegative,
    /// A finite number above 0.
    Positive,
    /// A number above 0 and at most this.
    PositiveAtMost(u32),
    /// A number >= 0 and below this.
    NonNegativeBelow(u32),
    /// A number from minus this to this.
    Within(u32),
    /// A number above 0 and below 1.
    Fraction,
    /// A buffer of at least this many elements.
    MinLen(usize),
    /// `None`: the type was built without the feature this setting asks for.
    Absent,
}

impl core::fmt::Display for Bound {
    /// The rule as the end of a sentence about the setting: "must be 1 to 4".
    ///
    /// ```
    /// use kestrel::Bound;
    /// assert_eq!(Bound::MinLen(480).to_string(), "must hold at least 480 elements");
    /// assert_eq!(Bound::NonNegative.to_string(), "must be a number >= 0");
    /// ```
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Bound::Range { min, max } => write!(f, "must be {min} to {max}"),
            Bound::OddRange { min, max } => write!(f, "must be odd, {min} to {max}"),
            Bound::AtLeast(n) => write!(f, "must be at least {n}"),
            Bound::AtMost(n) => write!(f, "must be at most {n}"),
            Bound::NonNegative => f.write_str("must be a number >= 0"),
            Bound::FiniteNonNegative => f.write_str("must be a finite number >= 0"),
            Bound::Positive => f.write_str("must be a finite number above 0"),
            Bound::PositiveAtMost(n) => write!(f, "must be a number above 0 and at most {n}"),
            Bound::NonNegativeBelow(n) => write!(f, "must be a number >= 0 and below {n}"),
            Bound::Within(n) => write!(f, "must be a number from -{n} to {n}"),
            Bound::Fraction => f.write_str("must be a number above 0 and below 1"),
            Bound::MinLen(n) => write!(f, "must hold at least {n} elements"),
            Bound::Absent => f.write_str("must be None"),
        }
    }
}

impl core::fmt::Display for ConfigError {
    /// The setting and its rule: "max_tracks must be 1 to 4".
    ///
    /// ```
    /// use kestrel::{Bound, ConfigError};
    /// let short = ConfigError { field: "buffers.storage", bound: Bound::MinLen(13_080) };
    /// assert_eq!(short.to_string(), "buffers.storage must hold at least 13080 elements");
    /// ```
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{} {}", self.field, self.bound)
    }
}

impl core::fmt::Debug for ConfigError {
    /// As a derived `Debug` would write it, but with the field written as it is: it is one of
    /// the library's own names, plain ASCII with nothing to escape, and escaping a `str` would
    /// link core's Unicode tables into every firmware that logs an error (about 5 KB of
    /// Cortex-M4 flash).
    ///
    /// ```
    /// use kestrel::{Bound, ConfigError};
    /// let refused = ConfigError { field: "lk.window", bound: Bound::OddRange { min: 3, max: 63 } };
    /// assert_eq!(
    ///     format!("{refused:?}"),
    ///     r#"ConfigError { field: "lk.window", bound: OddRange { min: 3, max: 63 } }"#
    /// );
    /// ```
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "ConfigError {{ field: \"{}\", bound: {:?} }}",
            self.field, self.bound
        )
    }
}

impl ConfigError {
    /// A refusal of `field` for breaking `bound`.
    pub(crate) const fn new(field: &'static str, bound: Bound) -> Self {
        Self { field, bound }
    }

    /// A buffer `field` shorter than `len` elements.
    pub(crate) const fn min_len(field: &'static str, len: usize) -> Self {
        Self::new(field, Bound::MinLen(len))
    }

    /// The same refusal named from the value that holds the refused settings: the path of
    /// `paths` that ends in `.` and this error's field (`"lk.window"` for `"window"`). A field
    /// no path ends in is left as it is (a buffer or a size passed beside the settings).
    pub(crate) fn nested(self, paths: &[&'static str]) -> Self {
        let field = self.field.as_bytes();
        let within = paths.iter().find(|path| {
            let head = path.as_bytes().strip_suffix(field);
            head.and_then(<[u8]>::last) == Some(&b'.')
        });
        match within {
            Some(path) => Self::new(path, self.bound),
            None => self,
        }
    }

    /// The same refusal with its field renamed by the first of `names`, `(from, to)` pairs,
    /// whose `from` it is: a buffer a function calls `"scratch"` is its caller's
    /// `"buffers.lk_scratch"`. Other fields are left as they are.
    pub(crate) fn renamed(self, names: &[(&str, &'static str)]) -> Self {
        match names.iter().find(|(from, _)| *from == self.field) {
            Some(&(_, to)) => Self::new(to, self.bound),
            None => self,
        }
    }
}

/// `n` as a bound's number, saturating at `u32::MAX` (no setting comes near it).
pub(crate) const fn bound_number(n: usize) -> u32 {
    if n > u32::MAX as usize {
        u32::MAX
    } else {
        // Below u32::MAX after the check above.
        #[allow(clippy::cast_possible_truncation)]
        let n = n as u32;
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_names_take_the_matching_path() {
        let window = ConfigError::new("window", Bound::OddRange { min: 3, max: 63 });
        let paths = ["lk.max_level", "lk.window", "grid.cols"];
        assert_eq!(window.nested(&paths).field, "lk.window");
        // Two levels: a tracker's LK window inside a flow sensor.
        let sensor = ["tracker.max_tracks", "tracker.lk.window"];
        assert_eq!(
            window.nested(&paths).nested(&sensor).field,
            "tracker.lk.window"
        );
        // A suffix that is not a whole field does not match, nor does a field of its own.
        let short = ConfigError::min_len("storage", 9);
        assert_eq!(short.nested(&["buffers.lk_storage"]).field, "storage");
        assert_eq!(short.nested(&["storage"]).field, "storage");
        assert_eq!(short.nested(&[]), short);
    }

    #[test]
    fn renamed_fields_take_the_first_match() {
        let short = ConfigError::min_len("scratch", 9);
        let names = [
            ("nodes", "buffers.nodes"),
            ("scratch", "buffers.lk_scratch"),
        ];
        assert_eq!(short.renamed(&names).field, "buffers.lk_scratch");
        assert_eq!(short.renamed(&names[..1]), short);
    }

    #[test]
    fn bound_numbers_saturate() {
        assert_eq!(bound_number(7), 7);
        assert_eq!(bound_number(usize::MAX), u32::MAX);
    }
}

//! The core LK on degenerate frames, worst-case intensities and bad input.
//!
//! Accuracy against ground truth and the f32 reference is in `lk_accuracy.rs`.

use kestrel::lk::{
    scratch_len, Illumination, LkError, LkParams, LucasKanade, PointTrack, TrackStatus,
};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::Point;
use kestrel::{Bound, ConfigError};
use kestrel::{ImageError, ImageView};

/// A smooth, textured test image shifted by (`dx`, `dy`): a few sinusoids, values in 20..235.
fn texture(w: usize, h: usize, dx: f32, dy: f32) -> Vec<u8> {
    (0..w * h)
        .map(|i| {
            let x = (i % w) as f32 - dx;
            let y = (i / w) as f32 - dy;
            // Periods from 13 to 90 px: fine detail for precision, coarse structure that
            // survives the pyramid's blur so large shifts are found at the coarse levels.
            let v = 0.35 * (x * 0.47).sin() * (y * 0.41).cos()
                + 0.8 * (x * 0.07 + y * 0.05).sin()
                + 0.7 * (x * 0.045 - y * 0.083).cos()
                + 0.5 * ((x + 2.0 * y) * 0.13).sin();
            (128.0 + 45.0 * v).round().clamp(0.0, 255.0) as u8
        })
        .collect()
}

struct Pair {
    a: Vec<u8>,
    b: Vec<u8>,
    w: usize,
    h: usize,
}

impl Pair {
    /// Tracks `points` with `params`, building both pyramids to `params.max_level`.
    fn track(&self, params: LkParams, points: &[Point]) -> Vec<PointTrack> {
        let levels = params.max_level;
        let mut sa = vec![0u8; pyramid_storage_len(self.w, self.h, levels)];
        let mut sb = sa.clone();
        let va = ImageView::packed(&self.a, self.w, self.h).unwrap();
        let vb = ImageView::packed(&self.b, self.w, self.h).unwrap();
        let prev = Pyramid::build(va, levels, &mut sa).unwrap();
        let next = Pyramid::build(vb, levels, &mut sb).unwrap();
        let lk = LucasKanade::new(params).unwrap();
        let mut out = vec![PointTrack::default(); points.len()];
        let mut scratch = vec![0i16; scratch_len(params.window)];
        lk.track_points(&prev, &next, points, None, &mut out, &mut scratch)
            .unwrap();
        out
    }
}

fn shifted(w: usize, h: usize, dx: f32, dy: f32) -> Pair {
    Pair {
        a: texture(w, h, 0.0, 0.0),
        b: texture(w, h, dx, dy),
        w,
        h,
    }
}

fn assert_moved(t: &PointTrack, from: (f32, f32), by: (f32, f32), tolerance: f32) {
    assert_eq!(t.status, TrackStatus::Tracked, "{t:?}");
    let (x, y) = t.position.to_f32();
    let err = ((x - from.0 - by.0).powi(2) + (y - from.1 - by.1).powi(2)).sqrt();
    assert!(
        err <= tolerance,
        "{from:?} moved to {:?}: error {err}",
        (x, y)
    );
}

/// Full-contrast 2 px stripes in both directions: every Scharr response is at or near its
/// extreme of 16 * 255, the worst case for the integer window sums.
fn stripes(w: usize, h: usize, shift: usize) -> Vec<u8> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w + shift, i / w);
            if ((x / 2) + (y / 2)) % 2 == 0 {
                255
            } else {
                0
            }
        })
        .collect()
}

#[test]
fn worst_case_contrast_does_not_overflow_31_and_63_px_windows() {
    for window in [31, 63] {
        for illumination in [Illumination::Plain, Illumination::GainBias] {
            let pair = Pair {
                a: stripes(160, 160, 0),
                b: stripes(160, 160, 1),
                w: 160,
                h: 160,
            };
            let params = LkParams {
                window,
                max_level: 0,
                illumination,
                ..LkParams::default()
            };
            // Content moves by -1 px in x when the pattern index is shifted by +1.
            let t = pair.track(params, &[Point::from_f32(80.0, 80.0)]);
            assert_moved(&t[0], (80.0, 80.0), (-1.0, 0.0), 0.01);
            assert!(t[0].residual.to_num::<f32>() < 0.5, "{:?}", t[0]);
        }
    }
}

#[test]
fn subpixel_shift_is_recovered_with_and_without_pyramid() {
    let pair = shifted(96, 80, 2.3, -1.7);
    for max_level in [0, 1, 3] {
        let params = LkParams {
            max_level,
            ..LkParams::default()
        };
        let t = pair.track(params, &[Point::from_f32(48.0, 40.0)]);
        assert_moved(&t[0], (48.0, 40.0), (2.3, -1.7), 0.05);
    }
}

#[test]
fn large_shift_needs_the_pyramid() {
    let pair = shifted(160, 120, 14.0, 9.0);
    let p = [Point::from_f32(80.0, 60.0)];
    let with = pair.track(LkParams::default(), &p);
    assert_moved(&with[0], (80.0, 60.0), (14.0, 9.0), 0.05);
    let without = pair.track(
        LkParams {
            max_level: 0,
            ..LkParams::default()
        },
        &p,
    );
    let (x, y) = without[0].position.to_f32();
    let err = ((x - 94.0).powi(2) + (y - 69.0).powi(2)).sqrt();
    assert!(
        !without[0].is_tracked() || err > 1.0,
        "a 17 px shift without a pyramid should fail: {without:?}"
    );
}

#[test]
fn flat_image_is_low_texture() {
    let pair = Pair {
        a: vec![100; 64 * 64],
        b: vec![100; 64 * 64],
        w: 64,
        h: 64,
    };
    let t = pair.track(LkParams::default(), &[Point::from_f32(32.0, 32.0)]);
    assert_eq!(t[0].status, TrackStatus::LowTexture);
}

#[test]
fn points_on_and_beyond_the_border() {
    let pair = shifted(64, 48, 0.5, 0.25);
    let points = [
        Point::from_f32(0.0, 0.0),
        Point::from_f32(63.0, 47.0),
        Point::from_f32(-0.01, 10.0),
        Point::from_f32(10.0, 47.01),
        Point::from_f32(-500.0, 9000.0),
    ];
    let t = pair.track(LkParams::default(), &points);
    // On the border the window repeats edge pixels; the point is tracked or honestly refused.
    for corner in &t[..2] {
        assert!(
            matches!(
                corner.status,
                TrackStatus::Tracked | TrackStatus::OutOfBounds | TrackStatus::LowTexture
            ),
            "{corner:?}"
        );
    }
    assert_moved(&t[0], (0.0, 0.0), (0.5, 0.25), 0.25);
    for beyond in &t[2..] {
        assert_eq!(beyond.status, TrackStatus::OutOfBounds);
    }
}

#[test]
fn one_pixel_and_odd_sized_frames() {
    let one = Pair {
        a: vec![10],
        b: vec![200],
        w: 1,
        h: 1,
    };
    let t = one.track(LkParams::default(), &[Point::from_f32(0.0, 0.0)]);
    assert_eq!(t[0].status, TrackStatus::LowTexture);

    for (w, h) in [(33, 17), (41, 41)] {
        let pair = shifted(w, h, 1.0, 0.5);
        let params = LkParams {
            window: 9,
            ..LkParams::default()
        };
        let centre = ((w / 2) as f32, (h / 2) as f32);
        let t = pair.track(params, &[Point::from_f32(centre.0, centre.1)]);
        assert_moved(&t[0], centre, (1.0, 0.5), 0.1);
    }

    // A frame smaller than the window: any status, but a position inside the frame if tracked.
    let tiny = shifted(7, 5, 1.0, 0.5);
    let t = tiny.track(LkParams::default(), &[Point::from_f32(3.0, 2.0)]);
    let (x, y) = t[0].position.to_f32();
    assert!(!t[0].is_tracked() || ((0.0..=6.0).contains(&x) && (0.0..=4.0).contains(&y)));
}

#[test]
fn initial_guess_reaches_beyond_the_pyramid() {
    let pair = shifted(200, 120, 40.0, 3.0);
    let params = LkParams {
        max_level: 1,
        ..LkParams::default()
    };
    let lk = LucasKanade::new(params).unwrap();
    let mut sa = vec![0u8; pyramid_storage_len(200, 120, 1)];
    let mut sb = sa.clone();
    let prev = Pyramid::build(ImageView::packed(&pair.a, 200, 120).unwrap(), 1, &mut sa).unwrap();
    let next = Pyramid::build(ImageView::packed(&pair.b, 200, 120).unwrap(), 1, &mut sb).unwrap();
    let mut scratch = vec![0i16; scratch_len(21)];
    let from = Point::from_f32(80.0, 60.0);
    let guess = Point::from_f32(118.0, 62.0);
    let t = lk
        .track_point(&prev, &next, from, Some(guess), &mut scratch)
        .unwrap();
    assert_moved(&t, (80.0, 60.0), (40.0, 3.0), 0.05);
}

#[test]
fn bad_parameters_are_errors() {
    let base = LkParams::default();
    let window = ("window", Bound::OddRange { min: 3, max: 63 });
    let epsilon = ("epsilon", Bound::FiniteNonNegative);
    let cases = [
        (LkParams { window: 20, ..base }, window),
        (LkParams { window: 65, ..base }, window),
        (LkParams { window: 1, ..base }, window),
        (
            LkParams {
                max_level: 8,
                ..base
            },
            ("max_level", Bound::AtMost(7)),
        ),
        (
            LkParams {
                max_iterations: 0,
                ..base
            },
            ("max_iterations", Bound::AtLeast(1)),
        ),
        (
            LkParams {
                epsilon: f32::NAN,
                ..base
            },
            epsilon,
        ),
        (
            LkParams {
                epsilon: -1.0,
                ..base
            },
            epsilon,
        ),
        (
            LkParams {
                min_eigen_threshold: f32::INFINITY,
                ..base
            },
            ("min_eigen_threshold", Bound::FiniteNonNegative),
        ),
    ];
    for (params, (field, bound)) in cases {
        let error = ConfigError { field, bound };
        assert_eq!(LucasKanade::new(params).unwrap_err(), error, "{params:?}");
    }
}

#[test]
fn bad_buffers_are_errors() {
    let pixels = vec![0u8; 100];
    assert_eq!(
        ImageView::packed(&pixels, 20, 6).unwrap_err(),
        ImageError::BufferTooSmall
    );
    assert_eq!(
        ImageView::packed(&pixels, 0, 6).unwrap_err(),
        ImageError::ZeroSize
    );
    let frame = ImageView::packed(&pixels, 10, 10).unwrap();
    let mut short = vec![0u8; pyramid_storage_len(10, 10, 2) - 1];
    assert_eq!(
        Pyramid::build(frame, 2, &mut short).unwrap_err(),
        ConfigError {
            field: "storage",
            bound: Bound::MinLen(pyramid_storage_len(10, 10, 2))
        }
    );

    let other = vec![0u8; 12 * 10];
    let prev = Pyramid::build(frame, 0, &mut []).unwrap();
    let next = Pyramid::build(ImageView::packed(&other, 12, 10).unwrap(), 0, &mut []).unwrap();
    let lk = LucasKanade::new(LkParams::default()).unwrap();
    let p = Point::from_f32(5.0, 5.0);
    let mut scratch = vec![0i16; scratch_len(21)];
    assert_eq!(
        lk.track_point(&prev, &next, p, None, &mut scratch)
            .unwrap_err(),
        LkError::FrameSizeMismatch
    );
    let mut small = vec![0i16; scratch_len(21) - 1];
    assert_eq!(
        lk.track_point(&prev, &prev, p, None, &mut small)
            .unwrap_err(),
        LkError::Config(ConfigError {
            field: "scratch",
            bound: Bound::MinLen(scratch_len(21))
        })
    );
    let mut out = vec![PointTrack::default(); 2];
    assert_eq!(
        lk.track_points(&prev, &prev, &[p], None, &mut out, &mut scratch)
            .unwrap_err(),
        LkError::LengthMismatch
    );
}

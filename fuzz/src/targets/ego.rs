//! Ego-motion with arbitrary tracks: model fits, RANSAC, homography algebra, the camera and
//! gyro derotation, the OPTICAL_FLOW_RAD accumulator and (feature `mavlink`) its encoding.
//!
//! No NaN or infinity may leave the module. RANSAC must refuse exactly the documented
//! parameters, flag `BadInput` exactly when a coordinate is invalid, report a failed estimate
//! as the identity with no support, and an `Ok` one with as many flags as inliers, each within
//! the threshold of the model, a quality of at least 1 and no more iterations than allowed. A
//! readout with quality 0 carries no flow. Every encoded frame decodes back to the readout.

use arbitrary::Arbitrary;
use kestrel::ego::MAX_COORDINATE;
use kestrel::ego::{
    fit, Camera, CameraParams, EgoMotion, EgoStatus, FlowRadAccumulator, Homography, ModelKind,
    OpticalFlowRad, Ransac, RansacError, RansacParams, Rotation,
};
use kestrel::ego::{FOCAL_RANGE, MAX_DISTORTION};
use kestrel::{Bound, ConfigError, Point};

/// A track: its previous and next position, pixels.
type Pair = ((f32, f32), (f32, f32));

/// More tracks only slow RANSAC down.
const MAX_TRACKS: usize = 64;

#[derive(Arbitrary, Debug)]
struct Input {
    truth: Truth,
    tracks: Vec<TrackInput>,
    kind: u8,
    threshold: f32,
    max_iterations: u16,
    confidence: f32,
    min_inliers: u16,
    seed: u64,
    flag_delta: i8,
    matrices: [[f32; 9]; 2],
    camera: CameraInput,
    gyro: [f32; 3],
    interval_us: u32,
    steps: Vec<FlowStep>,
}

/// A camera motion most tracks follow: shift, rotation, scale and perspective.
#[derive(Arbitrary, Debug)]
struct Truth {
    dx: i8,
    dy: i8,
    angle: i8,
    scale: i8,
    tilt: i8,
}

#[derive(Arbitrary, Debug)]
enum TrackInput {
    /// Anything, NaN and infinities included.
    Raw((f32, f32), (f32, f32)),
    /// A point moved by the truth, plus noise in 1/64 px.
    Follows { x: u8, y: u8, noise: (i8, i8) },
    /// Positions straight from the tracker's Q16 type.
    Q16(i32, i32, i32, i32),
}

#[derive(Arbitrary, Debug)]
enum CameraInput {
    Fov(u16, u16, f32),
    Params([f32; 6]),
}

#[derive(Arbitrary, Debug)]
enum FlowStep {
    /// The RANSAC estimate, or a motion of the caller's.
    Add {
        estimate: bool,
        matrix: Option<[f32; 9]>,
        quality: u8,
        status: u8,
        interval_us: u32,
        gyro: Option<[f32; 3]>,
    },
    Distance(f32, u64),
    Temperature(i16),
    Readout(u64, u8, [u8; 3]),
}

/// The decoded input, for reading a crash.
pub fn show(data: &[u8]) -> String {
    super::show::<Input>(data)
}

pub fn run(data: &[u8]) {
    let Some(input) = super::decode::<Input>(data) else {
        return;
    };
    let pairs: Vec<Pair> = input
        .tracks
        .iter()
        .take(MAX_TRACKS)
        .map(|t| track(t, &input.truth))
        .collect();
    let kind = [
        ModelKind::Translation,
        ModelKind::Similarity,
        ModelKind::Affine,
        ModelKind::Homography,
    ][usize::from(input.kind % 4)];
    check_fit(kind, &pairs);
    let estimate = check_ransac(&input, kind, &pairs);
    check_homographies(&input.matrices);
    let camera = check_camera(&input.camera);
    check_rotation(&camera, &input, &pairs, estimate.as_ref());
    check_flow_rad(camera, &input.steps, estimate.as_ref());
}

fn track(t: &TrackInput, truth: &Truth) -> Pair {
    match *t {
        TrackInput::Raw(prev, next) => (prev, next),
        TrackInput::Follows { x, y, noise } => {
            let prev = (f32::from(x), f32::from(y));
            let (nx, ny) = apply_truth(truth, prev);
            let next = (
                nx + f32::from(noise.0) / 64.0,
                ny + f32::from(noise.1) / 64.0,
            );
            (prev, next)
        }
        TrackInput::Q16(a, b, c, d) => {
            let (prev, next) = (Point::from_bits(a, b), Point::from_bits(c, d));
            (prev.to_f32(), next.to_f32())
        }
    }
}

fn apply_truth(t: &Truth, (x, y): (f32, f32)) -> (f32, f32) {
    let angle = f32::from(t.angle) / 1000.0;
    let scale = 1.0 + f32::from(t.scale) / 1000.0;
    let (s, c) = (angle.sin() * scale, angle.cos() * scale);
    let w = 1.0 + f32::from(t.tilt) * 1e-5 * x;
    (
        (c * x - s * y + f32::from(t.dx) / 8.0) / w,
        (s * x + c * y + f32::from(t.dy) / 8.0) / w,
    )
}

fn valid(&(prev, next): &Pair) -> bool {
    [prev.0, prev.1, next.0, next.1]
        .iter()
        .all(|v| v.abs() <= MAX_COORDINATE)
}

/// A homography is finite with `h33 = 1`.
fn check_homography(h: &Homography) {
    let m = h.matrix();
    assert!(m.iter().all(|v| v.is_finite()), "{m:?}");
    assert_eq!(m[8], 1.0, "{m:?}");
}

fn check_fit(kind: ModelKind, pairs: &[Pair]) {
    match fit(kind, pairs) {
        Ok(h) => {
            assert!(pairs.iter().all(valid), "a fit on invalid input");
            check_homography(&h);
            assert!(h.inverse().is_some(), "a fitted model is invertible");
        }
        Err(e) => assert!(
            pairs.iter().all(valid) || e == kestrel::ego::FitError::BadInput,
            "{e:?}"
        ),
    }
}

fn check_ransac(input: &Input, kind: ModelKind, pairs: &[Pair]) -> Option<EgoMotion> {
    let params = RansacParams {
        model: kind,
        threshold: input.threshold,
        max_iterations: input.max_iterations % 1000,
        confidence: input.confidence,
        min_inliers: input.min_inliers % 80,
        seed: input.seed,
    };
    let t = params.threshold;
    let expected = if !(t > 0.0 && t <= 1000.0) {
        Some(("threshold", Bound::PositiveAtMost(1000)))
    } else if params.max_iterations == 0 {
        Some(("max_iterations", Bound::AtLeast(1)))
    } else if !(params.confidence > 0.0 && params.confidence < 1.0) {
        Some(("confidence", Bound::Fraction))
    } else {
        None
    };
    let expected = expected.map(|(field, bound)| ConfigError { field, bound });
    let ransac = match Ransac::new(params) {
        Ok(r) => r,
        Err(e) => {
            assert_eq!(Some(e), expected);
            return None;
        }
    };
    assert_eq!(expected, None);
    let flags_len = pairs
        .len()
        .saturating_add_signed((input.flag_delta % 2).into());
    let mut flags = vec![true; flags_len];
    let motion = match ransac.estimate(pairs, &mut flags) {
        Ok(motion) => motion,
        Err(e) => {
            assert_eq!(
                (e, flags_len == pairs.len()),
                (RansacError::LengthMismatch, false)
            );
            return None;
        }
    };
    assert_eq!(flags_len, pairs.len());
    check_motion(&motion, &params, pairs, &flags);
    let mut again = vec![false; pairs.len()];
    assert_eq!(
        ransac.estimate(pairs, &mut again),
        Ok(motion),
        "not deterministic"
    );
    assert_eq!(again, flags);
    Some(motion)
}

fn check_motion(motion: &EgoMotion, params: &RansacParams, pairs: &[Pair], flags: &[bool]) {
    check_homography(&motion.model);
    assert!(motion.rms_residual.is_finite() && motion.rms_residual >= 0.0);
    assert!(motion.iterations <= params.max_iterations);
    assert_eq!(motion.kind, params.model);
    let all_valid = pairs.iter().all(valid);
    assert_eq!(
        motion.status == EgoStatus::BadInput,
        !all_valid,
        "{motion:?}"
    );
    if !motion.is_ok() {
        let failed = EgoMotion {
            iterations: motion.iterations,
            ..EgoMotion::failed(params.model, motion.status)
        };
        assert_eq!(*motion, failed);
        assert!(flags.iter().all(|f| !f), "flags on a failed estimate");
        return;
    }
    let flagged = flags.iter().filter(|&&f| f).count();
    assert_eq!(usize::from(motion.inliers), flagged);
    let consensus = usize::from(params.min_inliers).max(params.model.min_samples() + 1);
    assert!(flagged >= consensus, "{motion:?}");
    assert!(motion.quality >= 1);
    let t_sq = params.threshold * params.threshold;
    for (pair, &flag) in pairs.iter().zip(flags) {
        let error_sq = match motion.model.apply(pair.0) {
            Some((x, y)) => (x - pair.1 .0) * (x - pair.1 .0) + (y - pair.1 .1) * (y - pair.1 .1),
            None => f32::INFINITY,
        };
        assert_eq!(flag, error_sq < t_sq, "flag of {pair:?}: error² {error_sq}");
    }
    assert!(
        motion.rms_residual <= params.threshold * 1.001,
        "{motion:?}"
    );
}

/// `from_matrix`, `inverse`, `compose` and `apply` never give a non-finite value.
fn check_homographies(matrices: &[[f32; 9]; 2]) {
    let [a, b] = matrices.map(Homography::from_matrix);
    for h in [a, b].iter().flatten() {
        check_homography(h);
        if let Some(inverse) = h.inverse() {
            check_homography(&inverse);
        }
        for p in [(0.0, 0.0), (159.5, 119.5), (-4000.0, 3000.0)] {
            if let Some((x, y)) = h.apply(p) {
                assert!(x.is_finite() && y.is_finite());
            }
        }
    }
    if let (Some(a), Some(b)) = (a, b) {
        if let Some(ab) = a.compose(&b) {
            check_homography(&ab);
        }
    }
}

/// The fuzzed camera when it is valid, otherwise a plain one.
fn check_camera(input: &CameraInput) -> Camera {
    let params = match *input {
        CameraInput::Fov(w, h, fov) => CameraParams::from_horizontal_fov(w, h, fov),
        CameraInput::Params([fx, fy, px, py, k1, k2]) => CameraParams {
            focal_x: fx,
            focal_y: fy,
            principal_x: px,
            principal_y: py,
            k1,
            k2,
        },
    };
    match Camera::new(params) {
        Ok(camera) => {
            assert!(FOCAL_RANGE.contains(&params.focal_x) && FOCAL_RANGE.contains(&params.focal_y));
            assert!(params.principal_x.abs() <= MAX_COORDINATE);
            assert!(params.principal_y.abs() <= MAX_COORDINATE);
            assert!(params.k1.abs() <= MAX_DISTORTION && params.k2.abs() <= MAX_DISTORTION);
            camera
        }
        Err(_) => {
            Camera::new(CameraParams::from_horizontal_fov(160, 120, 1.0)).expect("the plain camera")
        }
    }
}

fn finite(p: Option<(f32, f32)>) {
    if let Some((x, y)) = p {
        assert!(x.is_finite() && y.is_finite(), "({x}, {y})");
    }
}

/// Gyro rotations, prediction and derotation stay finite.
fn check_rotation(camera: &Camera, input: &Input, pairs: &[Pair], estimate: Option<&EgoMotion>) {
    let rotations = [
        Rotation::from_vector(input.gyro),
        Rotation::from_body_rates(input.gyro, input.interval_us),
        Rotation::from_integrated_gyro(input.gyro, input.interval_us),
    ];
    for rotation in rotations.iter().flatten() {
        let v = rotation.vector();
        assert!(v.iter().all(|c| c.is_finite()));
        assert!(v.iter().map(|c| c * c).sum::<f32>() <= 1.0 + 1e-5, "{v:?}");
        if let Some(h) = camera.rotation_homography(rotation) {
            check_homography(&h);
            finite(camera.angular_flow(&h));
        }
        for &(prev, next) in pairs.iter().take(8) {
            finite(camera.undistort(prev));
            finite(camera.distort(prev));
            finite(camera.predict(rotation, prev));
            finite(camera.derotated_flow(rotation, prev, next));
        }
        let points: Vec<Point> = pairs
            .iter()
            .take(8)
            .map(|&(p, _)| Point::from_f32(p.0, p.1))
            .collect();
        let mut guesses = vec![Point::default(); points.len()];
        assert!(camera
            .predict_points(rotation, &points, &mut guesses)
            .is_ok());
        let mut short = vec![Point::default(); points.len() + 1];
        assert!(camera
            .predict_points(rotation, &points, &mut short)
            .is_err());
    }
    if let Some(motion) = estimate {
        finite(camera.angular_flow(&motion.model));
    }
}

/// The accumulator's readouts are finite and self-consistent, and encode faithfully.
fn check_flow_rad(camera: Camera, steps: &[FlowStep], estimate: Option<&EgoMotion>) {
    let mut acc = FlowRadAccumulator::new(camera, 7);
    let mut added = 0u16;
    for step in steps.iter().take(64) {
        match *step {
            FlowStep::Add {
                estimate: use_estimate,
                matrix,
                quality,
                status,
                interval_us,
                gyro,
            } => {
                let motion = match estimate.filter(|_| use_estimate) {
                    Some(m) => *m,
                    None => EgoMotion {
                        model: matrix
                            .and_then(Homography::from_matrix)
                            .unwrap_or(Homography::IDENTITY),
                        quality,
                        ..EgoMotion::failed(ModelKind::Homography, status_of(status))
                    },
                };
                acc.add(&motion, interval_us, gyro);
                added = added.saturating_add(1);
                assert_eq!(acc.frames(), added);
            }
            FlowStep::Distance(metres, at) => acc.set_distance(metres, at),
            FlowStep::Temperature(t) => acc.set_temperature(t),
            FlowStep::Readout(time, sequence, buffer) => {
                let reading = acc.readout(time);
                check_reading(&reading, added);
                added = 0;
                assert_eq!(acc.frames(), 0);
                encode(&reading, sequence, buffer);
            }
        }
    }
}

fn status_of(code: u8) -> EgoStatus {
    match code % 5 {
        0 => EgoStatus::Ok,
        1 => EgoStatus::TooFewTracks,
        2 => EgoStatus::Degenerate,
        3 => EgoStatus::NoConsensus,
        _ => EgoStatus::BadInput,
    }
}

fn check_reading(r: &OpticalFlowRad, frames: u16) {
    assert!(
        r.integrated_x.is_finite() && r.integrated_y.is_finite(),
        "{r:?}"
    );
    if r.quality == 0 {
        assert_eq!((r.integrated_x, r.integrated_y), (0.0, 0.0), "{r:?}");
    }
    if frames == 0 {
        assert_eq!(r.quality, 0);
    }
    for g in [r.integrated_xgyro, r.integrated_ygyro, r.integrated_zgyro] {
        assert!(g.is_none_or(f32::is_finite), "{r:?}");
    }
    assert!(
        r.distance.is_none_or(|d| d.is_finite() && d >= 0.0),
        "{r:?}"
    );
    assert_eq!(r.sensor_id, 7);
}

#[cfg(feature = "mavlink")]
fn encode(reading: &OpticalFlowRad, sequence: u8, buffer: [u8; 3]) {
    super::mavlink_frame::check(reading, sequence, buffer);
}

#[cfg(not(feature = "mavlink"))]
fn encode(_: &OpticalFlowRad, _: u8, _: [u8; 3]) {}

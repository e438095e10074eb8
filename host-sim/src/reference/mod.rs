//! PLACEHOLDER, to be replaced by the f32 reference Lucas-Kanade being written on its own
//! branch: this file is overwritten when that branch is merged.
//!
//! Until then it keeps the reference's public API so `host-sim flow --reference` builds and runs
//! end to end, by running the library itself and converting its results to `f32`. It is not an
//! independent reference and must not be used to validate the library.

use kestrel::lk::{scratch_len, LkParams, LucasKanade, PointTrack, TrackStatus};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::Point;

use crate::Frame;

/// One point's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefTrack {
    /// Estimated x in the next frame.
    pub x: f32,
    /// Estimated y in the next frame.
    pub y: f32,
    /// Whether the point was tracked, and why not.
    pub status: TrackStatus,
    /// Mean absolute intensity residual over the window, grey levels.
    pub residual: f32,
}

/// Tracks `points` from `prev` to `next`; one result per point, in order.
pub fn track_points(
    prev: &Frame,
    next: &Frame,
    points: &[(f32, f32)],
    guesses: Option<&[(f32, f32)]>,
    params: &LkParams,
) -> Vec<RefTrack> {
    let lost = RefTrack {
        x: f32::NAN,
        y: f32::NAN,
        status: TrackStatus::OutOfBounds,
        residual: 0.0,
    };
    let (Ok(lk), Ok(prev_view), Ok(next_view)) =
        (LucasKanade::new(*params), prev.view(), next.view())
    else {
        return vec![lost; points.len()];
    };
    let levels = params.max_level;
    let mut prev_storage = vec![0; pyramid_storage_len(prev.width, prev.height, levels)];
    let mut next_storage = vec![0; pyramid_storage_len(next.width, next.height, levels)];
    let (Ok(prev_pyramid), Ok(next_pyramid)) = (
        Pyramid::build(prev_view, levels, &mut prev_storage),
        Pyramid::build(next_view, levels, &mut next_storage),
    ) else {
        return vec![lost; points.len()];
    };
    let to_points = |list: &[(f32, f32)]| -> Vec<Point> {
        list.iter().map(|&(x, y)| Point::from_f32(x, y)).collect()
    };
    let starts = to_points(points);
    let guesses = guesses.map(to_points);
    let mut tracks = vec![PointTrack::default(); points.len()];
    let mut scratch = vec![0; scratch_len(params.window)];
    let tracked = lk.track_points(
        &prev_pyramid,
        &next_pyramid,
        &starts,
        guesses.as_deref(),
        &mut tracks,
        &mut scratch,
    );
    if tracked.is_err() {
        return vec![lost; points.len()];
    }
    tracks
        .iter()
        .map(|track| {
            let (x, y) = track.position.to_f32();
            RefTrack {
                x,
                y,
                status: track.status,
                residual: track.residual.to_num(),
            }
        })
        .collect()
}

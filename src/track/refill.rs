//! Finding where to start new tracks: detect on one pyramid level away from the live tracks,
//! space the new corners out, and bucket them over the frame.

use super::config::{Detector, Refill};
use super::follow::moves;
use crate::detect::{Corner, ExclusionMask, Region};
use crate::frame::ImageView;
use crate::q16::Point;
use crate::ConfigError;
use heapless::Vec;

/// The memory one detection works in.
pub(super) struct DetectBuffers<'b> {
    /// FAST's rows.
    pub fast_rows: &'b mut [u8],
    /// Shi-Tomasi's scratch.
    pub scratch: &'b mut [i32],
    /// The candidates; the result is a prefix.
    pub candidates: &'b mut [Corner],
}

/// Finds new corners on `level_image`, pyramid level `refill.level` of a
/// `width` x `height` frame, at least `refill.min_distance` px from every position in `live`
/// and from each other, twice that from every position in `cooling`, at most
/// `refill.grid.per_cell` per cell counting `live`, and none that the frame's median step
/// `motion` soon takes out of the view ([`leaves_soon`]).
///
/// Returns the corners, strongest first, in full-resolution coordinates: a prefix of
/// `buffers.candidates`.
pub(super) fn new_corners<'b>(
    refill: &Refill,
    level_image: &ImageView<'_>,
    (width, height): (usize, usize),
    (live, cooling, motion): (&[Point], &[(Point, u32)], Option<Point>),
    buffers: DetectBuffers<'b>,
) -> Result<&'b [Corner], ConfigError> {
    let level = refill.level;
    // Round the radius up so that the spacing is at least min_distance at full resolution.
    let radius = refill.min_distance.div_ceil(1 << level);
    let mut mask = ExclusionMask::new(level_image.width(), level_image.height());
    for &p in live {
        mask.exclude_around(at_level(p, level), radius);
    }
    for &(p, _) in cooling {
        mask.exclude_around(at_level(p, level), radius.saturating_mul(2));
    }
    // Keep new corners far enough from the edge that most of their window sees the frame:
    // LK repeats the edge pixels beyond it, a pattern that does not move with the scene.
    let border = usize::from(refill.border).div_ceil(1 << level);
    let region = Region::full(level_image).clip(level_image.width(), level_image.height(), border);
    let found = match &refill.detector {
        Detector::Fast(fast) => fast.detect(
            level_image,
            region,
            Some(&mask),
            buffers.fast_rows,
            buffers.candidates,
        ),
        Detector::ShiTomasi(shi_tomasi) => shi_tomasi.detect(
            level_image,
            region,
            Some(&mask),
            buffers.scratch,
            buffers.candidates,
        ),
    }?;
    // Each count below is of a prefix of the slice it came from (the detectors write the
    // candidates from the start, spacing and the grid keep a prefix of theirs), so every
    // range is inside its slice.
    debug_assert!(found <= buffers.candidates.len());
    let found = buffers.candidates.get_mut(..found).unwrap_or(&mut []);
    // Before the spacing and the grid: a corner about to leave takes no one's place.
    let staying = match motion {
        Some(motion) => keep_staying(found, refill, motion, level, (width, height)),
        None => found.len(),
    };
    debug_assert!(staying <= found.len());
    let found = found.get_mut(..staying).unwrap_or(&mut []);
    let spaced = space_out(found, &mut mask, radius);
    debug_assert!(spaced <= found.len());
    let spaced = found.get_mut(..spaced).unwrap_or(&mut []);
    for corner in spaced.iter_mut() {
        corner.position = at_full_resolution(corner.position, level);
    }
    let selected = refill.grid.select(width, height, spaced, live)?;
    debug_assert!(selected <= spaced.len());
    Ok(spaced.get(..selected).unwrap_or(&[]))
}

/// Whether a corner at `p` would come within `refill.border` px of the edge of a `width` x
/// `height` frame within [`Refill::leaving_within`] frames of `motion` (the frame's median
/// step), taken at most a quarter of the frame across; false when `motion` is under half a
/// pixel.
fn leaves_soon(refill: &Refill, p: Point, motion: Point, (width, height): (usize, usize)) -> bool {
    let (mx, my) = (i64::from(motion.x.to_bits()), i64::from(motion.y.to_bits()));
    if refill.leaving_within == 0 || !moves(motion) {
        return false;
    }
    let frames = i64::from(refill.leaving_within);
    let border = i64::from(refill.border) << 16;
    // Frame sides are at most MAX_DIMENSION: far inside i64.
    #[allow(clippy::cast_possible_wrap)]
    let stays = |at: i32, step: i64, side: usize| {
        let side = side as i64;
        let most = side.saturating_mul(1 << 14);
        let to = i64::from(at).saturating_add(
            step.saturating_mul(frames)
                .clamp(most.saturating_neg(), most),
        );
        let last = side
            .saturating_sub(1)
            .saturating_mul(1 << 16)
            .saturating_sub(border);
        (border..=last).contains(&to)
    };
    !(stays(p.x.to_bits(), mx, width) && stays(p.y.to_bits(), my, height))
}

/// Where young tracks failed lately, whatever the tracker's capacity: refill keeps away from
/// them, and marks the corners it refuses.
pub(super) trait Cooling {
    /// The spots, each with the frame it was marked in.
    fn spots(&self) -> &[(Point, u32)];
    /// Marks `at` in `frame`, forgetting the oldest spot when full.
    fn mark(&mut self, at: Point, frame: u32);
}

/// Where young tracks failed a gate lately, and in which frame, oldest first: new tracks keep
/// away from them for [`Refill::cooldown`] frames.
#[derive(Debug)]
pub(super) struct FailedSpots<const N: usize> {
    spots: Vec<(Point, u32), N>,
}

impl<const N: usize> FailedSpots<N> {
    pub(super) const fn new() -> Self {
        Self { spots: Vec::new() }
    }

    /// Forgets the spots marked `cooldown` frames or more before `frame`.
    pub(super) fn expire(&mut self, frame: u32, cooldown: u16) {
        let cooldown = u32::from(cooldown);
        self.spots
            .retain(|&(_, marked)| frame.wrapping_sub(marked) < cooldown);
    }

    /// Forgets every spot.
    pub(super) fn clear(&mut self) {
        self.spots.clear();
    }
}

impl<const N: usize> Cooling for FailedSpots<N> {
    /// The spots and their frames, oldest first.
    fn spots(&self) -> &[(Point, u32)] {
        &self.spots
    }

    /// Marks `at`, where a young track failed (or a corner was refused) in `frame`; when full,
    /// the oldest spot makes room.
    fn mark(&mut self, at: Point, frame: u32) {
        if self.spots.is_full() {
            self.spots.remove(0);
        }
        let pushed = self.spots.push((at, frame));
        debug_assert!(pushed.is_ok(), "room was made");
    }
}

/// Keeps, in their order, the corners of pyramid level `level` that `motion` does not soon take
/// out of the `size` frame ([`leaves_soon`]); moves them to the front and returns how many
/// there are.
fn keep_staying(
    corners: &mut [Corner],
    refill: &Refill,
    motion: Point,
    level: usize,
    size: (usize, usize),
) -> usize {
    keep_front(corners, |corner| {
        let at = at_full_resolution(corner.position, level);
        !leaves_soon(refill, at, motion, size)
    })
}

/// Keeps, strongest first, the corners outside `mask`, excluding `radius` around each one kept;
/// moves them to the front and returns how many there are.
///
/// The detector already skipped corners near live tracks; this keeps the new ones apart, which
/// FAST's 3 x 3 suppression alone does not.
fn space_out(corners: &mut [Corner], mask: &mut ExclusionMask, radius: u16) -> usize {
    keep_front(corners, |corner| {
        let (x, y) = corner.pixel();
        let free = !mask.is_excluded(x, y);
        if free {
            mask.exclude_around(corner.position, radius);
        }
        free
    })
}

/// Moves the corners `keep` takes, asked in order, to the front, in their order; returns how
/// many there are.
fn keep_front(corners: &mut [Corner], mut keep: impl FnMut(&Corner) -> bool) -> usize {
    let mut kept = 0;
    for i in 0..corners.len() {
        let Some(&corner) = corners.get(i) else {
            break;
        };
        if !keep(&corner) {
            continue;
        }
        if let Some(slot) = corners.get_mut(kept) {
            *slot = corner;
            kept = kept.saturating_add(1);
        }
    }
    kept
}

/// A full-resolution position in the coordinates of pyramid level `level`.
///
/// Pixel `i` of level `l + 1` is centred on pixel `2i` of level `l` (the subsampling keeps the
/// even pixels), so positions simply halve.
fn at_level(p: Point, level: usize) -> Point {
    Point::from_bits(p.x.to_bits() >> level, p.y.to_bits() >> level)
}

/// A position on pyramid level `level` in full-resolution coordinates.
fn at_full_resolution(p: Point, level: usize) -> Point {
    let up = |bits: i32| bits.saturating_mul(1 << level);
    Point::from_bits(up(p.x.to_bits()), up(p.y.to_bits()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_halve_positions() {
        let p = Point::from_f32(100.0, 61.0);
        assert_eq!(at_level(p, 1), Point::from_f32(50.0, 30.5));
        assert_eq!(at_full_resolution(Point::from_f32(50.0, 30.5), 1), p);
        assert_eq!(at_level(p, 0), p);
        let far = Point::from_f32(30000.0, -30000.0);
        assert_eq!(
            at_full_resolution(far, 3),
            Point::from_bits(i32::MAX, i32::MIN)
        );
    }

    #[test]
    fn failed_spots_expire_after_the_cooldown_and_the_oldest_make_room() {
        let mut failed = FailedSpots::<2>::new();
        let at = |x| Point::from_f32(x, 0.0);
        failed.mark(at(1.0), 10);
        failed.mark(at(2.0), 11);
        // Full: the oldest goes.
        failed.mark(at(3.0), 12);
        assert_eq!(failed.spots(), &[(at(2.0), 11), (at(3.0), 12)]);
        // A cooldown of 2 frames at frame 13 keeps what was marked in frame 12 only.
        failed.expire(13, 2);
        assert_eq!(failed.spots(), &[(at(3.0), 12)]);
        // Frame numbers wrap.
        failed.mark(at(4.0), u32::MAX);
        failed.expire(0, 2);
        assert_eq!(failed.spots(), &[(at(4.0), u32::MAX)]);
        failed.expire(0, 0);
        assert!(failed.spots().is_empty());
    }

    #[test]
    fn corners_a_moving_camera_soon_takes_out_of_the_view_leave_soon() {
        let refill = Refill::default();
        let size = (320, 240);
        let leaves = |x: f32, y: f32, dx: f32, dy: f32| {
            leaves_soon(
                &refill,
                Point::from_f32(x, y),
                Point::from_f32(dx, dy),
                size,
            )
        };
        // 2 px a frame to the right: 20 frames carry a corner 40 px, up to 8 px from the edge.
        assert!(leaves(272.0, 100.0, 2.0, 0.0));
        assert!(!leaves(270.0, 100.0, 2.0, 0.0));
        // Towards the top-left, on either axis.
        assert!(leaves(100.0, 30.0, -1.0, -1.5));
        assert!(!leaves(100.0, 40.0, -1.0, -1.5));
        // Under half a pixel a frame the camera is taken as still.
        assert!(!leaves(310.0, 100.0, 0.45, 0.0));
        // A fast pan is taken a quarter of the frame across at most: 80 px, not 200.
        assert!(!leaves(150.0, 100.0, 10.0, 0.0));
        assert!(leaves(240.0, 100.0, 10.0, 0.0));
        // Off: nothing leaves.
        let off = Refill {
            leaving_within: 0,
            ..refill
        };
        assert!(!leaves_soon(
            &off,
            Point::from_f32(310.0, 100.0),
            Point::from_f32(5.0, 0.0),
            size
        ));
    }

    #[test]
    fn spacing_keeps_the_strongest_of_close_corners() {
        let mut corners = [
            Corner::new(50, 50, 90),
            Corner::new(52, 51, 80),
            Corner::new(80, 50, 70),
            Corner::new(50, 20, 60),
        ];
        let mut mask = ExclusionMask::new(160, 120);
        mask.exclude_around(Point::from_f32(80.0, 52.0), 4);
        let kept = space_out(&mut corners, &mut mask, 4);
        assert_eq!(kept, 2);
        assert_eq!(corners[0].pixel(), (50, 50));
        assert_eq!(corners[1].pixel(), (50, 20));
    }
}

//! FAST-9, Shi-Tomasi and grid bucketing with arbitrary frames, regions, masks, buffers and
//! settings.
//!
//! Beyond "no panic": each detector must refuse exactly the settings and buffers it documents,
//! report at most its output's length of corners, strongest first, each inside the region and
//! the detector's border, outside the mask, scored as the public score function scores that
//! pixel. Without suppression FAST must be complete: no qualifying pixel left out that beats
//! the weakest one kept. Shi-Tomasi must respect its minimum distance, and the grid its
//! per-cell allowance.

use super::picture::{Frame, Picture};
use arbitrary::Arbitrary;
use kestrel::detect::{
    fast9_score, fast_scratch_len, min_eigen_score, shi_tomasi_scratch_len, Corner, ExclusionMask,
    Fast, Grid, Region, ShiTomasi, FAST_BORDER, MAX_BLOCK, MAX_CELLS_PER_SIDE,
};
use kestrel::ImageView;
use kestrel::{Bound, ConfigError, Point};

#[derive(Arbitrary, Debug)]
struct Input {
    picture: Picture,
    region: RegionInput,
    mask: Vec<(i32, i32)>,
    mask_radius: u16,
    use_mask: bool,
    capacity: u8,
    scratch_delta: i8,
    fast_threshold: u8,
    fast_nonmax: bool,
    block: u8,
    quality: f32,
    min_distance: u16,
    grid: (u8, u8, u8),
    tracks: Vec<(i32, i32)>,
}

/// A region that is either near the frame or anywhere in `usize`.
#[derive(Arbitrary, Debug)]
enum RegionInput {
    Full,
    Small(u8, u8, u8, u8),
    Huge(usize, usize, usize, usize),
}

/// The decoded input, for reading a crash.
pub fn show(data: &[u8]) -> String {
    super::show::<Input>(data)
}

pub fn run(data: &[u8]) {
    let Some(input) = super::decode::<Input>(data) else {
        return;
    };
    let frame = input.picture.render();
    let Some(image) = frame.view() else {
        return;
    };
    let region = match input.region {
        RegionInput::Full => Region::full(&image),
        RegionInput::Small(x, y, w, h) => Region::new(x.into(), y.into(), w.into(), h.into()),
        RegionInput::Huge(x, y, w, h) => Region::new(x, y, w, h),
    };
    let mut mask = ExclusionMask::new(image.width(), image.height());
    let points: Vec<Point> = input
        .mask
        .iter()
        .map(|&(x, y)| Point::from_bits(x, y))
        .collect();
    mask.exclude_all(&points, input.mask_radius);
    let mask = input.use_mask.then_some(&mask);
    let capacity = usize::from(input.capacity % 80);

    check_fast(&input, &image, region, mask, capacity);
    let corners = check_shi_tomasi(&input, &image, region, mask, capacity);
    check_grid(&input, &frame, corners);
}

fn check_fast(
    input: &Input,
    image: &ImageView<'_>,
    region: Region,
    mask: Option<&ExclusionMask>,
    capacity: usize,
) {
    let detector = Fast {
        threshold: input.fast_threshold,
        nonmax: input.fast_nonmax,
    };
    let needed = if detector.nonmax {
        fast_scratch_len(image.width())
    } else {
        0
    };
    let mut scratch = vec![0u8; needed.saturating_add_signed(input.scratch_delta.into())];
    let mut out = vec![Corner::default(); capacity];
    let result = detector.detect(image, region, mask, &mut scratch, &mut out);
    if scratch.len() < needed {
        let needed = ConfigError {
            field: "scratch",
            bound: Bound::MinLen(needed),
        };
        assert_eq!(result, Err(needed));
        return;
    }
    let n = result.expect("FAST refused valid buffers");
    assert!(n <= capacity);
    let area = region.clip(image.width(), image.height(), FAST_BORDER);
    let found = &out[..n];
    check_corners(found, area, mask);
    for c in found {
        let (x, y) = c.pixel();
        let score = fast9_score(image, x, y).expect("a reported corner has a FAST score");
        assert_eq!(u32::from(score), c.score, "FAST score at ({x}, {y})");
        assert!(score >= detector.threshold);
    }
    if !detector.nonmax {
        check_fast_complete(detector.threshold, image, area, mask, found, capacity);
    }
}

/// Without suppression every corner of the area is either reported or weaker than all that
/// were (when the output is full).
fn check_fast_complete(
    threshold: u8,
    image: &ImageView<'_>,
    area: Region,
    mask: Option<&ExclusionMask>,
    found: &[Corner],
    capacity: usize,
) {
    for y in area.y..area.y + area.height {
        for x in area.x..area.x + area.width {
            if mask.is_some_and(|m| m.is_excluded(x, y)) {
                continue;
            }
            let Some(score) = fast9_score(image, x, y).filter(|&s| s >= threshold) else {
                continue;
            };
            let corner = Corner::new(x, y, score.into());
            if found.contains(&corner) {
                continue;
            }
            assert_eq!(found.len(), capacity, "corner ({x}, {y}) missed");
            let Some(weakest) = found.last() else {
                continue;
            };
            assert!(
                !corner.is_stronger_than(weakest),
                "corner ({x}, {y}) beats the weakest kept"
            );
        }
    }
}

fn check_shi_tomasi(
    input: &Input,
    image: &ImageView<'_>,
    region: Region,
    mask: Option<&ExclusionMask>,
    capacity: usize,
) -> Vec<Corner> {
    let detector = ShiTomasi {
        block: usize::from(input.block % 10),
        quality_level: input.quality,
        min_distance: input.min_distance % 40,
    };
    let needed = shi_tomasi_scratch_len(image.width(), capacity);
    let mut scratch = vec![0i32; needed.saturating_add_signed(input.scratch_delta.into())];
    let mut out = vec![Corner::default(); capacity];
    let result = detector.detect(image, region, mask, &mut scratch, &mut out);
    let block_ok = detector.block % 2 == 1 && (3..=MAX_BLOCK).contains(&detector.block);
    let quality_ok = (0.0..=1.0).contains(&detector.quality_level);
    let expected_error = if !block_ok {
        Some(("block", Bound::OddRange { min: 3, max: 7 }))
    } else if !quality_ok {
        Some(("quality_level", Bound::Range { min: 0, max: 1 }))
    } else if scratch.len() < needed {
        Some(("scratch", Bound::MinLen(needed)))
    } else {
        None
    };
    let expected_error = expected_error.map(|(field, bound)| ConfigError { field, bound });
    assert_eq!(detector.validate().is_ok(), block_ok && quality_ok);
    if let Some(error) = expected_error {
        assert_eq!(result, Err(error));
        return Vec::new();
    }
    let n = result.expect("Shi-Tomasi refused valid settings and buffers");
    assert!(n <= capacity);
    let area = region.clip(image.width(), image.height(), detector.block / 2 + 1);
    let found = &out[..n];
    check_corners(found, area, mask);
    for (i, c) in found.iter().enumerate() {
        let (x, y) = c.pixel();
        let score = min_eigen_score(image, x, y, detector.block).expect("a scored corner");
        assert_eq!(score, c.score, "Shi-Tomasi score at ({x}, {y})");
        assert!(c.score > 0);
        let d = u64::from(detector.min_distance);
        for other in &found[..i] {
            let (ox, oy) = other.pixel();
            let dist_sq = (x.abs_diff(ox) as u64).pow(2) + (y.abs_diff(oy) as u64).pow(2);
            assert!(
                dist_sq >= d * d,
                "({x}, {y}) closer than {d} to ({ox}, {oy})"
            );
        }
    }
    found.to_vec()
}

/// Common to both detectors: sorted strongest first, distinct, whole pixels inside `area`
/// and outside the mask.
fn check_corners(found: &[Corner], area: Region, mask: Option<&ExclusionMask>) {
    for (i, c) in found.iter().enumerate() {
        let (x, y) = c.pixel();
        assert_eq!(*c, Corner::new(x, y, c.score), "corner off a pixel centre");
        assert!(area.contains(x, y), "corner ({x}, {y}) outside {area:?}");
        assert!(!mask.is_some_and(|m| m.is_excluded(x, y)), "masked corner");
        if let Some(next) = found.get(i + 1) {
            assert!(c.is_stronger_than(next), "not sorted at {i}");
        }
    }
}

/// Bucketing keeps a strongest-first subset within each cell's allowance.
fn check_grid(input: &Input, frame: &Frame, mut corners: Vec<Corner>) {
    let (cols, rows, per_cell) = input.grid;
    let grid = Grid {
        cols: usize::from(cols % 36),
        rows: usize::from(rows % 36),
        per_cell,
    };
    let sides = 1..=MAX_CELLS_PER_SIDE;
    let valid = sides.contains(&grid.cols) && sides.contains(&grid.rows);
    // Corners anywhere, not only those a detector found.
    corners.extend(input.tracks.iter().map(|&(x, y)| Corner {
        position: Point::from_bits(x, y),
        score: (x as u32) >> 20,
    }));
    let tracks: Vec<Point> = input
        .tracks
        .iter()
        .map(|&(x, y)| Point::from_bits(y, x))
        .collect();
    let before = corners.clone();
    let (w, h) = (frame.width, frame.height);
    let result = grid.select(w, h, &mut corners, &tracks);
    if !valid {
        let field = if sides.contains(&grid.cols) {
            "rows"
        } else {
            "cols"
        };
        let bound = Bound::Range { min: 1, max: 32 };
        assert_eq!(result, Err(ConfigError { field, bound }));
        return;
    }
    let n = result.expect("a valid grid");
    assert!(n <= before.len());
    let cell_index = |p: &Point| {
        pixel_of(p)
            .and_then(|(x, y)| grid.cell_of(w, h, x, y))
            .map(|(cx, cy)| cy * grid.cols + cx)
    };
    let mut tracked = vec![0usize; grid.cols * grid.rows];
    for i in tracks.iter().filter_map(cell_index) {
        tracked[i] += 1;
    }
    let mut added = vec![0usize; grid.cols * grid.rows];
    let mut pool = before;
    for (i, c) in corners[..n].iter().enumerate() {
        let cell = cell_index(&c.position).expect("a kept corner is on the frame");
        added[cell] += 1;
        let taken = pool
            .iter()
            .position(|p| p == c)
            .expect("kept corners were given");
        pool.swap_remove(taken);
        if let Some(next) = corners[..n].get(i + 1) {
            assert!(!next.is_stronger_than(c), "grid output not sorted at {i}");
        }
    }
    for (cell, (&new, &old)) in added.iter().zip(&tracked).enumerate() {
        // Track counts saturate at 255 per cell.
        let allowed = usize::from(per_cell).saturating_sub(old.min(255));
        assert!(
            new <= allowed,
            "cell {cell}: {new} new corners, {allowed} allowed"
        );
    }
}

/// The pixel holding a point, `None` for negative coordinates.
fn pixel_of(p: &Point) -> Option<(usize, usize)> {
    let x = usize::try_from(p.x.to_bits() >> 16).ok()?;
    let y = usize::try_from(p.y.to_bits() >> 16).ok()?;
    Some((x, y))
}

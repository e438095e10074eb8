//! Corner detectors against independent oracles: `imageproc`'s FAST-9 and a plain `f64`
//! Shi-Tomasi written out below, on hand-made patterns and seeded random images.

use imageproc::corners::{corners_fast9, fast_corner_score, Fast as FastVariant};
use imageproc::image::GrayImage;
use kestrel::detect::{
    fast9_score, fast_scratch_len, min_eigen_score, shi_tomasi_scratch_len, Corner, ExclusionMask,
    Fast, Grid, Region, ShiTomasi,
};
use kestrel::ImageView;
use kestrel::{Bound, ConfigError, Point};
use std::collections::{BTreeMap, BTreeSet};

/// A seeded xorshift64* generator: the same images on every run and machine.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// A test frame: owned pixels and their size.
struct Frame {
    pixels: Vec<u8>,
    width: usize,
    height: usize,
}

impl Frame {
    fn view(&self) -> ImageView<'_> {
        ImageView::packed(&self.pixels, self.width, self.height).unwrap()
    }

    fn gray_image(&self) -> GrayImage {
        GrayImage::from_raw(self.width as u32, self.height as u32, self.pixels.clone()).unwrap()
    }

    fn at(&self, x: usize, y: usize) -> u8 {
        self.pixels[y * self.width + x]
    }

    /// Uniform noise.
    fn noise(width: usize, height: usize, seed: u64) -> Self {
        let mut rng = Rng(seed);
        let pixels = (0..width * height).map(|_| rng.below(256) as u8).collect();
        Self {
            pixels,
            width,
            height,
        }
    }

    /// Noise box-blurred `passes` times over 3 x 3 and stretched to the full grey range: blobs
    /// and corners of many sizes and contrasts, closer to a scene than white noise.
    fn texture(width: usize, height: usize, seed: u64, passes: usize) -> Self {
        let mut rng = Rng(seed);
        let mut v: Vec<f64> = (0..width * height).map(|_| rng.below(256) as f64).collect();
        for _ in 0..passes {
            let src = v.clone();
            for y in 0..height {
                for x in 0..width {
                    let mut sum = 0.0;
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let sx = (x as i64 + dx).clamp(0, width as i64 - 1) as usize;
                            let sy = (y as i64 + dy).clamp(0, height as i64 - 1) as usize;
                            sum += src[sy * width + sx];
                        }
                    }
                    v[y * width + x] = sum / 9.0;
                }
            }
        }
        let (lo, hi) = v
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &p| (l.min(p), h.max(p)));
        let pixels = v
            .iter()
            .map(|p| ((p - lo) / (hi - lo) * 255.0).round() as u8)
            .collect();
        Self {
            pixels,
            width,
            height,
        }
    }

    fn from_fn(width: usize, height: usize, f: impl Fn(usize, usize) -> u8) -> Self {
        let pixels = (0..width * height)
            .map(|i| f(i % width, i / width))
            .collect();
        Self {
            pixels,
            width,
            height,
        }
    }
}

/// The test images: noise and textures of two sizes.
fn random_frames() -> Vec<Frame> {
    let mut frames = Vec::new();
    for seed in 1..=3 {
        frames.push(Frame::noise(64, 48, seed));
        frames.push(Frame::texture(160, 120, seed * 7, 1));
        frames.push(Frame::texture(160, 120, seed * 11, 3));
    }
    frames
}

fn run_fast(
    frame: &Frame,
    fast: Fast,
    region: Region,
    mask: Option<&ExclusionMask>,
) -> Vec<Corner> {
    let mut scratch = vec![0u8; fast_scratch_len(frame.width)];
    let mut out = vec![Corner::default(); frame.width * frame.height];
    let n = fast
        .detect(&frame.view(), region, mask, &mut scratch, &mut out)
        .unwrap();
    out.truncate(n);
    out
}

fn by_pixel(corners: &[Corner]) -> BTreeMap<(usize, usize), u32> {
    corners.iter().map(|c| (c.pixel(), c.score)).collect()
}

fn assert_strongest_first(corners: &[Corner]) {
    for pair in corners.windows(2) {
        assert!(
            pair[0].is_stronger_than(&pair[1]),
            "{:?} before {:?}",
            pair[0],
            pair[1]
        );
    }
}

// ---------------------------------------------------------------------------------------------
// FAST-9: hand-made patterns.

fn square(width: usize, height: usize, lo: usize, hi: usize) -> Frame {
    Frame::from_fn(width, height, |x, y| {
        if (lo..hi).contains(&x) && (lo..hi).contains(&y) {
            200
        } else {
            20
        }
    })
}

const SQUARE_CORNERS: [(usize, usize); 4] = [(8, 8), (15, 8), (8, 15), (15, 15)];

#[test]
fn fast_finds_the_corners_of_a_bright_square() {
    let frame = square(24, 24, 8, 16);
    let all = run_fast(
        &frame,
        Fast {
            threshold: 20,
            nonmax: false,
        },
        Region::full(&frame.view()),
        None,
    );
    let found = by_pixel(&all);
    for corner in SQUARE_CORNERS {
        assert_eq!(found.get(&corner), Some(&179), "{corner:?}");
    }
    // Every detection belongs to one of the four corners.
    for &(x, y) in found.keys() {
        assert!(
            SQUARE_CORNERS
                .iter()
                .any(|&(cx, cy)| x.abs_diff(cx) <= 2 && y.abs_diff(cy) <= 2),
            "({x}, {y})"
        );
    }
}

#[test]
fn fast_nonmax_keeps_one_corner_per_square_corner() {
    // A tilted background makes the scores around each corner distinct (on a flat one they tie
    // and strict suppression keeps none, as in OpenCV).
    let frame = Frame::from_fn(24, 24, |x, y| {
        if (8..16).contains(&x) && (8..16).contains(&y) {
            200
        } else {
            (20 + x + 3 * y) as u8
        }
    });
    let kept = run_fast(&frame, Fast::default(), Region::full(&frame.view()), None);
    assert_eq!(kept.len(), 4, "{kept:?}");
    for corner in SQUARE_CORNERS {
        assert!(
            kept.iter().any(|c| {
                let (x, y) = c.pixel();
                x.abs_diff(corner.0) <= 2 && y.abs_diff(corner.1) <= 2
            }),
            "{corner:?}: {kept:?}"
        );
    }
    assert_strongest_first(&kept);
}

#[test]
fn fast_sees_nothing_on_edges_and_flat_images() {
    let edge = Frame::from_fn(32, 32, |x, _| if x < 16 { 10 } else { 240 });
    let diagonal = Frame::from_fn(32, 32, |x, y| if x + y < 32 { 10 } else { 240 });
    let flat = Frame::from_fn(32, 32, |_, _| 128);
    for frame in [&edge, &diagonal, &flat] {
        for threshold in [0, 10, 100] {
            let fast = Fast {
                threshold,
                nonmax: false,
            };
            assert!(run_fast(frame, fast, Region::full(&frame.view()), None).is_empty());
        }
    }
}

#[test]
fn fast_nine_arc_is_a_corner_eight_is_not() {
    // Put an arc of bright pixels on the circle around (5, 5) of an 11 x 11 frame.
    let circle = [
        (0i64, -3i64),
        (1, -3),
        (2, -2),
        (3, -1),
        (3, 0),
        (3, 1),
        (2, 2),
        (1, 3),
        (0, 3),
        (-1, 3),
        (-2, 2),
        (-3, 1),
        (-3, 0),
        (-3, -1),
        (-2, -2),
        (-1, -3),
    ];
    for start in 0..16 {
        for (len, expected) in [(8, None), (9, Some(39)), (12, Some(39)), (16, Some(39))] {
            let mut pixels = vec![60u8; 121];
            for k in 0..len {
                let (dx, dy) = circle[(start + k) % 16];
                pixels[((5 + dy) * 11 + 5 + dx) as usize] = 100;
            }
            let image = ImageView::packed(&pixels, 11, 11).unwrap();
            assert_eq!(
                fast9_score(&image, 5, 5),
                expected,
                "start {start} len {len}"
            );
            let frame = Frame {
                pixels: pixels.clone(),
                width: 11,
                height: 11,
            };
            let at_39 = Fast {
                threshold: 39,
                nonmax: false,
            };
            let at_40 = Fast {
                threshold: 40,
                ..at_39
            };
            let found = |fast| by_pixel(&run_fast(&frame, fast, Region::full(&image), None));
            assert_eq!(found(at_39).contains_key(&(5, 5)), expected.is_some());
            assert!(!found(at_40).contains_key(&(5, 5)));
        }
    }
}

#[test]
fn fast_score_is_the_largest_detecting_threshold() {
    // Hand-computed: centre 100, a 10-arc of +12..=+21 and six pixels at -90. The dark run has
    // only 6 pixels; the best bright arc of 9 drops the +12 end: min +13, score 12.
    let frame = Frame::from_fn(7, 7, |_, _| 100);
    let mut pixels = frame.pixels.clone();
    let circle = [
        (3, 0),
        (4, 0),
        (5, 1),
        (6, 2),
        (6, 3),
        (6, 4),
        (5, 5),
        (4, 6),
        (3, 6),
        (2, 6),
        (1, 5),
        (0, 4),
        (0, 3),
        (0, 2),
        (1, 1),
        (2, 0),
    ];
    for (k, &(x, y)) in circle.iter().enumerate() {
        pixels[y * 7 + x] = if k < 10 { 112 + k as u8 } else { 10 };
    }
    let frame = Frame { pixels, ..frame };
    assert_eq!(fast9_score(&frame.view(), 3, 3), Some(12));
    for threshold in 0..=20u8 {
        let fast = Fast {
            threshold,
            nonmax: true,
        };
        let found = run_fast(&frame, fast, Region::full(&frame.view()), None);
        assert_eq!(
            found.len(),
            usize::from(threshold <= 12),
            "threshold {threshold}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// FAST-9 against imageproc.

/// OpenCV's suppression applied to a set of corners: keep those whose score beats every
/// neighbouring corner's.
fn strict_local_maxima(corners: &BTreeMap<(usize, usize), u32>) -> BTreeMap<(usize, usize), u32> {
    corners
        .iter()
        .filter(|&(&(x, y), &score)| {
            (y.saturating_sub(1)..=y + 1).all(|ny| {
                (x.saturating_sub(1)..=x + 1).all(|nx| {
                    (nx, ny) == (x, y) || corners.get(&(nx, ny)).is_none_or(|&s| s < score)
                })
            })
        })
        .map(|(&p, &s)| (p, s))
        .collect()
}

#[test]
fn fast_matches_imageproc_on_random_images() {
    let (mut compared, mut corners_seen, mut kept_seen, mut ties_kept) = (0, 0, 0, 0);
    for frame in random_frames() {
        let image = frame.gray_image();
        for threshold in [1u8, 5, 10, 20, 40, 80] {
            let oracle: BTreeMap<(usize, usize), u32> = corners_fast9(&image, threshold)
                .iter()
                .map(|c| ((c.x as usize, c.y as usize), c.score as u32))
                .collect();
            let plain = Fast {
                threshold,
                nonmax: false,
            };
            let all = run_fast(&frame, plain, Region::full(&frame.view()), None);
            assert_strongest_first(&all);
            assert_eq!(by_pixel(&all), oracle, "threshold {threshold}");

            let kept = run_fast(
                &frame,
                Fast {
                    nonmax: true,
                    ..plain
                },
                Region::full(&frame.view()),
                None,
            );
            assert_strongest_first(&kept);
            assert_eq!(by_pixel(&kept), strict_local_maxima(&oracle));

            // imageproc's own suppression breaks ties in raster order instead of dropping both
            // corners, so it keeps a superset.
            let tie_breaking: BTreeSet<(usize, usize)> =
                imageproc::suppress::local_maxima(&corners_fast9(&image, threshold), 1)
                    .iter()
                    .map(|c| (c.x as usize, c.y as usize))
                    .collect();
            assert!(by_pixel(&kept).keys().all(|p| tie_breaking.contains(p)));
            ties_kept += tie_breaking.len() - kept.len();

            compared += 1;
            corners_seen += oracle.len();
            kept_seen += kept.len();
        }
    }
    println!(
        "FAST vs imageproc: {compared} image/threshold pairs, {corners_seen} corners, \
         {kept_seen} after suppression, 0 mismatches; imageproc's tie-breaking suppression \
         keeps {ties_kept} more"
    );
    assert!(corners_seen > 10_000 && kept_seen > 1_000);
}

#[test]
fn fast_score_matches_imageproc_at_every_pixel() {
    let mut corners = 0;
    for frame in random_frames().iter().take(3) {
        let image = frame.gray_image();
        let detected: BTreeSet<(u32, u32)> = corners_fast9(&image, 0)
            .iter()
            .map(|c| (c.x, c.y))
            .collect();
        for y in 0..frame.height {
            for x in 0..frame.width {
                let ours = fast9_score(&frame.view(), x, y);
                let theirs = detected
                    .contains(&(x as u32, y as u32))
                    .then(|| fast_corner_score(&image, 0, x as u32, y as u32, FastVariant::Nine));
                assert_eq!(ours, theirs, "({x}, {y})");
                corners += usize::from(ours.is_some());
            }
        }
    }
    assert!(corners > 1000);
}

#[test]
fn fast_threshold_zero_matches_imageproc() {
    let frame = Frame::texture(64, 48, 99, 2);
    let oracle: BTreeMap<(usize, usize), u32> = corners_fast9(&frame.gray_image(), 0)
        .iter()
        .map(|c| ((c.x as usize, c.y as usize), c.score as u32))
        .collect();
    let all = run_fast(
        &frame,
        Fast {
            threshold: 0,
            nonmax: false,
        },
        Region::full(&frame.view()),
        None,
    );
    assert_eq!(by_pixel(&all), oracle);
    // Score-0 corners survive suppression when no corner beats them.
    let kept = run_fast(
        &frame,
        Fast {
            threshold: 0,
            nonmax: true,
        },
        Region::full(&frame.view()),
        None,
    );
    assert_eq!(by_pixel(&kept), strict_local_maxima(&oracle));
}

// ---------------------------------------------------------------------------------------------
// FAST-9: regions, masks, capacity and bad input.

#[test]
fn fast_region_and_mask_filter_the_full_result() {
    let frame = Frame::texture(160, 120, 5, 1);
    let full = run_fast(&frame, Fast::default(), Region::full(&frame.view()), None);
    let region = Region::new(37, 20, 50, 61);
    let mut mask = ExclusionMask::new(160, 120);
    mask.exclude_all(
        &[Point::from_f32(60.0, 40.0), Point::from_f32(80.5, 70.2)],
        8,
    );
    let filtered: Vec<Corner> = full
        .iter()
        .copied()
        .filter(|c| {
            let (x, y) = c.pixel();
            region.contains(x, y) && !mask.is_excluded(x, y)
        })
        .collect();
    assert!(filtered.len() > 20);
    assert_eq!(
        run_fast(&frame, Fast::default(), region, Some(&mask)),
        filtered
    );
}

#[test]
fn fast_capacity_keeps_the_strongest() {
    let frame = Frame::texture(160, 120, 8, 1);
    let full = run_fast(&frame, Fast::default(), Region::full(&frame.view()), None);
    assert!(full.len() > 50);
    for capacity in [0, 1, 7, 50] {
        let mut scratch = vec![0u8; fast_scratch_len(160)];
        let mut out = vec![Corner::default(); capacity];
        let n = Fast::default()
            .detect(
                &frame.view(),
                Region::full(&frame.view()),
                None,
                &mut scratch,
                &mut out,
            )
            .unwrap();
        assert_eq!(n, capacity);
        assert_eq!(out, full[..capacity]);
    }
}

#[test]
fn fast_bad_input_is_harmless() {
    let frame = Frame::texture(64, 48, 3, 1);
    let view = frame.view();
    let fast = Fast::default();
    let mut out = [Corner::default(); 16];
    let mut scratch = [0u8; fast_scratch_len(64)];
    for region in [
        Region::new(10, 10, 0, 5),
        Region::new(64, 0, 10, 10),
        Region::new(0, 48, 10, 10),
        Region::new(usize::MAX, usize::MAX, usize::MAX, usize::MAX),
        Region::new(0, 0, 3, 3),
    ] {
        assert_eq!(
            fast.detect(&view, region, None, &mut scratch, &mut out),
            Ok(0)
        );
    }
    let huge = Region::new(0, 0, usize::MAX, usize::MAX);
    assert!(
        fast.detect(&view, huge, None, &mut scratch, &mut out)
            .unwrap()
            > 0
    );
    assert_eq!(
        fast.detect(&view, huge, None, &mut scratch[..191], &mut out),
        Err(ConfigError {
            field: "scratch",
            bound: Bound::MinLen(192)
        })
    );
    let plain = Fast {
        nonmax: false,
        ..fast
    };
    assert!(plain.detect(&view, huge, None, &mut [], &mut out).unwrap() > 0);
    assert_eq!(fast.detect(&view, huge, None, &mut scratch, &mut []), Ok(0));
    // Frames smaller than the circle.
    for (w, h) in [(1, 1), (6, 6), (7, 7), (100, 6), (6, 100)] {
        let tiny = Frame::noise(w, h, 4);
        let mut scratch = vec![0u8; fast_scratch_len(w)];
        let region = Region::full(&tiny.view());
        assert!(fast
            .detect(&tiny.view(), region, None, &mut scratch, &mut out)
            .is_ok());
    }
    for (x, y) in [(0, 0), (63, 47), (64, 48), (usize::MAX, 3)] {
        assert_eq!(fast9_score(&view, x, y), None);
    }
}

// ---------------------------------------------------------------------------------------------
// Shi-Tomasi against a plain f64 computation.

/// `2 λmin` of the structure tensor of (`x`, `y`), from Sobel gradients in `f64`.
fn reference_two_lambda(frame: &Frame, x: usize, y: usize, block: usize) -> Option<f64> {
    let r = block / 2;
    let border = r + 1;
    if x < border || y < border || x + border >= frame.width || y + border >= frame.height {
        return None;
    }
    let p = |x: usize, y: usize| f64::from(frame.at(x, y));
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for v in y - r..=y + r {
        for u in x - r..=x + r {
            let gx = p(u + 1, v - 1) - p(u - 1, v - 1)
                + 2.0 * (p(u + 1, v) - p(u - 1, v))
                + p(u + 1, v + 1)
                - p(u - 1, v + 1);
            let gy = p(u - 1, v + 1) - p(u - 1, v - 1)
                + 2.0 * (p(u, v + 1) - p(u, v - 1))
                + p(u + 1, v + 1)
                - p(u + 1, v - 1);
            a += gx * gx;
            b += gx * gy;
            c += gy * gy;
        }
    }
    Some((a + c) - ((a - c) * (a - c) + 4.0 * b * b).sqrt())
}

#[test]
fn shi_tomasi_score_matches_f64() {
    let (mut pixels, mut exact) = (0usize, 0usize);
    for frame in random_frames().iter().take(6) {
        for block in [3, 5, 7] {
            for y in 0..frame.height {
                for x in 0..frame.width {
                    let ours = min_eigen_score(&frame.view(), x, y, block);
                    let reference = reference_two_lambda(frame, x, y, block);
                    match (ours, reference) {
                        (None, None) => {}
                        (Some(s), Some(r)) => {
                            // The integer score is floor(2 λmin); allow f64's own rounding.
                            let s = f64::from(s);
                            assert!(
                                s <= r + 1e-6 && s > r - 1.0 - 1e-6,
                                "({x}, {y}): {s} vs {r}"
                            );
                            pixels += 1;
                            exact += usize::from(s == r.floor());
                        }
                        _ => panic!("({x}, {y}) block {block}: {ours:?} vs {reference:?}"),
                    }
                }
            }
        }
    }
    println!("Shi-Tomasi vs f64: {pixels} scores, {exact} equal to floor(2 lambda_min) in f64");
    assert_eq!(exact, pixels);
}

/// The whole Shi-Tomasi pipeline written the obvious way over a full score image.
fn reference_shi_tomasi(
    frame: &Frame,
    params: &ShiTomasi,
    region: Region,
    mask: Option<&ExclusionMask>,
    capacity: usize,
) -> Vec<Corner> {
    let (w, h) = (frame.width, frame.height);
    let score = |x: usize, y: usize| -> u32 {
        reference_two_lambda(frame, x, y, params.block).map_or(0, |r| r.floor() as u32)
    };
    let scores: Vec<u32> = (0..w * h).map(|i| score(i % w, i / w)).collect();
    let at = |x: i64, y: i64| {
        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
            0
        } else {
            scores[y as usize * w + x as usize]
        }
    };
    let mut candidates = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let s = at(x as i64, y as i64);
            let local_max =
                (-1..=1).all(|dy| (-1..=1).all(|dx| at(x as i64 + dx, y as i64 + dy) <= s));
            if s > 0
                && local_max
                && region.contains(x, y)
                && !mask.is_some_and(|m| m.is_excluded(x, y))
            {
                candidates.push(Corner::new(x, y, s));
            }
        }
    }
    candidates.sort_by(|a, b| {
        b.score
            .cmp(&a.score)
            .then(a.pixel().1.cmp(&b.pixel().1))
            .then(a.pixel().0.cmp(&b.pixel().0))
    });
    candidates.truncate(capacity);
    let max = candidates.first().map_or(0, |c| c.score);
    let q = (params.quality_level * 65536.0 + 0.5) as u64;
    candidates.retain(|c| (u64::from(c.score) << 16) > u64::from(max) * q);
    let d = i64::from(params.min_distance);
    let mut kept: Vec<Corner> = Vec::new();
    for c in candidates {
        let (x, y) = c.pixel();
        let far = kept.iter().all(|k| {
            let (kx, ky) = k.pixel();
            let (dx, dy) = (x as i64 - kx as i64, y as i64 - ky as i64);
            dx * dx + dy * dy >= d * d
        });
        if far {
            kept.push(c);
        }
    }
    kept
}

fn run_shi_tomasi(
    frame: &Frame,
    params: &ShiTomasi,
    region: Region,
    mask: Option<&ExclusionMask>,
    capacity: usize,
) -> Vec<Corner> {
    let mut scratch = vec![0i32; shi_tomasi_scratch_len(frame.width, capacity)];
    let mut out = vec![Corner::default(); capacity];
    let n = params
        .detect(&frame.view(), region, mask, &mut scratch, &mut out)
        .unwrap();
    assert!(n <= capacity);
    out.truncate(n);
    out
}

#[test]
fn shi_tomasi_matches_the_reference_pipeline() {
    let mut mask = ExclusionMask::new(160, 120);
    mask.exclude_all(
        &[Point::from_f32(30.0, 30.0), Point::from_f32(120.0, 90.0)],
        10,
    );
    let (mut runs, mut corners) = (0, 0);
    for (i, frame) in random_frames().iter().enumerate() {
        let full = Region::full(&frame.view());
        let cases = [
            (ShiTomasi::default(), full, None, 100),
            (
                ShiTomasi {
                    min_distance: 0,
                    quality_level: 0.0,
                    ..ShiTomasi::default()
                },
                full,
                None,
                5000,
            ),
            (
                ShiTomasi {
                    block: 5,
                    quality_level: 0.05,
                    min_distance: 4,
                },
                full,
                None,
                300,
            ),
            (
                ShiTomasi {
                    block: 7,
                    quality_level: 0.2,
                    min_distance: 20,
                },
                full,
                None,
                40,
            ),
            (ShiTomasi::default(), Region::new(20, 15, 41, 33), None, 64),
            (
                ShiTomasi {
                    min_distance: 1,
                    ..ShiTomasi::default()
                },
                full,
                Some(&mask),
                200,
            ),
            (
                ShiTomasi {
                    quality_level: 1.0,
                    ..ShiTomasi::default()
                },
                full,
                None,
                10,
            ),
            (ShiTomasi::default(), full, None, 1),
        ];
        for (case, (params, region, mask, capacity)) in cases.into_iter().enumerate() {
            let mask = mask.filter(|_| frame.width == 160);
            let ours = run_shi_tomasi(frame, &params, region, mask, capacity);
            let reference = reference_shi_tomasi(frame, &params, region, mask, capacity);
            assert_eq!(ours, reference, "frame {i} case {case}");
            assert_strongest_first(&ours);
            runs += 1;
            corners += ours.len();
        }
    }
    println!("Shi-Tomasi vs reference pipeline: {runs} runs, {corners} corners, 0 mismatches");
}

#[test]
fn shi_tomasi_quality_and_distance_hold() {
    let frame = Frame::texture(160, 120, 21, 2);
    let params = ShiTomasi {
        block: 3,
        quality_level: 0.1,
        min_distance: 12,
    };
    let found = run_shi_tomasi(&frame, &params, Region::full(&frame.view()), None, 200);
    assert!(found.len() > 20);
    let max = found[0].score;
    for (i, a) in found.iter().enumerate() {
        assert!(f64::from(a.score) > 0.1 * f64::from(max) - 1.0);
        for b in &found[..i] {
            let (ax, ay) = a.pixel();
            let (bx, by) = b.pixel();
            assert!(ax.abs_diff(bx).pow(2) + ay.abs_diff(by).pow(2) >= 144);
        }
    }
    // A prefix of a larger run is the smaller run's result when nothing else limits it.
    let unlimited = ShiTomasi {
        min_distance: 0,
        quality_level: 0.0,
        ..params
    };
    let big = run_shi_tomasi(&frame, &unlimited, Region::full(&frame.view()), None, 400);
    let small = run_shi_tomasi(&frame, &unlimited, Region::full(&frame.view()), None, 25);
    assert_eq!(small, big[..25]);
}

#[test]
fn shi_tomasi_bad_input_is_harmless() {
    let frame = Frame::texture(64, 48, 3, 1);
    let view = frame.view();
    let full = Region::full(&view);
    let st = ShiTomasi::default();
    let mut out = [Corner::default(); 16];
    let mut scratch = vec![0i32; shi_tomasi_scratch_len(64, 16)];
    for block in [0, 1, 2, 4, 9, usize::MAX] {
        let bad = ShiTomasi { block, ..st };
        assert_eq!(
            bad.detect(&view, full, None, &mut scratch, &mut out),
            Err(ConfigError {
                field: "block",
                bound: Bound::OddRange { min: 3, max: 7 }
            })
        );
    }
    for quality_level in [-0.01, 1.01, f32::NAN, f32::INFINITY] {
        let bad = ShiTomasi {
            quality_level,
            ..st
        };
        assert_eq!(
            bad.detect(&view, full, None, &mut scratch, &mut out),
            Err(ConfigError {
                field: "quality_level",
                bound: Bound::Range { min: 0, max: 1 }
            })
        );
    }
    assert_eq!(
        st.detect(&view, full, None, &mut scratch[..100], &mut out),
        Err(ConfigError {
            field: "scratch",
            bound: Bound::MinLen(shi_tomasi_scratch_len(64, 16))
        })
    );
    for region in [
        Region::new(10, 10, 0, 5),
        Region::new(64, 0, 10, 10),
        Region::new(usize::MAX, usize::MAX, usize::MAX, usize::MAX),
        Region::new(0, 0, 2, 2),
    ] {
        assert_eq!(
            st.detect(&view, region, None, &mut scratch, &mut out),
            Ok(0)
        );
    }
    assert_eq!(st.detect(&view, full, None, &mut scratch, &mut []), Ok(0));
    let huge = Region::new(0, 0, usize::MAX, usize::MAX);
    assert!(
        st.detect(&view, huge, None, &mut scratch, &mut out)
            .unwrap()
            > 0
    );
    for (w, h) in [(1, 1), (4, 4), (5, 5), (6, 6), (200, 3), (3, 200)] {
        let tiny = Frame::noise(w, h, 5);
        let mut scratch = vec![0i32; shi_tomasi_scratch_len(w, 16)];
        for block in [3, 5, 7] {
            let st = ShiTomasi { block, ..st };
            let region = Region::full(&tiny.view());
            let found = st.detect(&tiny.view(), region, None, &mut scratch, &mut out);
            assert!(found.is_ok());
        }
    }
    // A flat frame has no corner at all.
    let flat = Frame::from_fn(64, 48, |_, _| 77);
    assert_eq!(
        st.detect(&flat.view(), full, None, &mut scratch, &mut out),
        Ok(0)
    );
}

// ---------------------------------------------------------------------------------------------
// Grid bucketing.

#[test]
fn grid_caps_each_cell_and_covers_a_textured_frame() {
    let frame = Frame::texture(160, 120, 13, 1);
    let mut corners = run_shi_tomasi(
        &frame,
        &ShiTomasi {
            min_distance: 3,
            ..ShiTomasi::default()
        },
        Region::full(&frame.view()),
        None,
        500,
    );
    let detected = corners.clone();
    let grid = Grid {
        cols: 8,
        rows: 6,
        per_cell: 3,
    };
    let n = grid.select(160, 120, &mut corners, &[]).unwrap();
    let kept = &corners[..n];
    assert_strongest_first(kept);
    let mut per_cell = BTreeMap::new();
    for c in kept {
        let (x, y) = c.pixel();
        *per_cell
            .entry(grid.cell_of(160, 120, x, y).unwrap())
            .or_insert(0) += 1;
    }
    assert_eq!(per_cell.len(), 48, "every cell has corners");
    assert!(per_cell.values().all(|&k| k == 3));
    // Each kept corner is one of the 3 strongest detected in its cell.
    for c in kept {
        let (x, y) = c.pixel();
        let cell = grid.cell_of(160, 120, x, y);
        let stronger = detected
            .iter()
            .filter(|d| {
                let (dx, dy) = d.pixel();
                grid.cell_of(160, 120, dx, dy) == cell && d.is_stronger_than(c)
            })
            .count();
        assert!(stronger < 3);
    }
}

#[test]
fn grid_counts_existing_tracks_against_the_cap() {
    let frame = Frame::texture(160, 120, 17, 1);
    let mut corners = run_shi_tomasi(
        &frame,
        &ShiTomasi::default(),
        Region::full(&frame.view()),
        None,
        300,
    );
    let grid = Grid {
        cols: 4,
        rows: 3,
        per_cell: 2,
    };
    // Two tracks fill cell (0, 0); one half-fills cell (3, 2); one track is off the frame.
    let tracks = [
        Point::from_f32(5.0, 5.0),
        Point::from_f32(30.0, 20.0),
        Point::from_f32(150.0, 110.0),
        Point::from_f32(-40.0, 10.0),
    ];
    let n = grid.select(160, 120, &mut corners, &tracks).unwrap();
    let mut per_cell = BTreeMap::new();
    for c in &corners[..n] {
        let (x, y) = c.pixel();
        *per_cell
            .entry(grid.cell_of(160, 120, x, y).unwrap())
            .or_insert(0) += 1;
    }
    assert_eq!(per_cell.get(&(0, 0)), None);
    assert_eq!(per_cell.get(&(3, 2)), Some(&1));
    assert_eq!(per_cell.len(), 11);
    assert_eq!(n, 10 * 2 + 1);
}

#[test]
fn grid_over_fast_corners_with_a_mask() {
    let frame = Frame::texture(160, 120, 19, 1);
    let tracks = [Point::from_f32(40.0, 40.0), Point::from_f32(100.0, 80.0)];
    let mut mask = ExclusionMask::new(160, 120);
    mask.exclude_all(&tracks, 10);
    let mut corners = run_fast(
        &frame,
        Fast::default(),
        Region::full(&frame.view()),
        Some(&mask),
    );
    assert!(corners.iter().all(|c| {
        let (x, y) = c.pixel();
        x.abs_diff(40).max(y.abs_diff(40)) > 10 && x.abs_diff(100).max(y.abs_diff(80)) > 10
    }));
    let grid = Grid {
        cols: 4,
        rows: 4,
        per_cell: 1,
    };
    let n = grid.select(160, 120, &mut corners, &tracks).unwrap();
    // Each track's cell is skipped; the other 14 cells get one corner each.
    assert_eq!(n, 14);
}

//! The moving-object pipeline as `host-sim motion` runs it, over a short sequence: the dense
//! grid of each frame pair, the camera's dominant motion, the motion mask and its boxes, the
//! boxes expected from the pairs before ([`BoxPersistence::append_expected`]), their outlines
//! at pixel level ([`Outliner::outline`]) and the runs that confirm them
//! ([`BoxPersistence::confirm`]).
//!
//! The frames are a scene moved between frames, with an optional object pasted over it that
//! moves its own way, and now and then a frame of another size. Every stage must refuse
//! exactly what its documentation says (a frame of another size, short buffers), and its
//! output must hold: outlines and confirmed boxes inside the frame, no more than their buffers
//! hold, confirmed boxes taken from the outlines in order, no box confirmed on the first pair
//! when runs of two or more are asked for.

use super::picture::{Change, Frame, Picture};
use arbitrary::Arbitrary;
use kestrel::dense::{
    mask_words, motion_scratch_len, outline_scratch_len, BoxPersistence, BoxRules, DenseError,
    DenseFlow, DenseParams, DominantFitParams, DominantMotion, GridLayout, GridNode, MotionBox,
    MotionDetector, MotionParams, OutlineParams, Outliner,
};
use kestrel::lk::scratch_len;
use kestrel::pyramid::{level_size, pyramid_storage_len, Pyramid};
use kestrel::{Bound, ConfigError};

/// Boxes the persistence remembers: few, so that a full list is reached.
const REMEMBERED: usize = 4;

#[derive(Arbitrary, Debug)]
struct Input {
    scene: Picture,
    /// The later frames: the scene under each change (at most four frames in all).
    moves: Vec<Change>,
    mover: Option<Mover>,
    /// A frame index (modulo 8) rendered at another size: refused, and the pair after it
    /// joins the frames on either side.
    resized: u8,
    cell: u8,
    window: u8,
    max_level: u8,
    threshold: f32,
    min_nodes: u8,
    outline: Option<OutlineInput>,
    persist_pairs: u8,
    /// Capacity of the box buffers, 0 to 11.
    boxes: u8,
}

/// An object pasted over the scene: its own picture, a square from (`x`, `y`) moving by
/// (`vx`, `vy`) px a frame.
#[derive(Arbitrary, Debug)]
struct Mover {
    picture: Picture,
    x: u8,
    y: u8,
    side: u8,
    vx: i8,
    vy: i8,
}

#[derive(Arbitrary, Debug)]
struct OutlineInput {
    margin: u8,
    min_gain: u16,
    min_pixels: u8,
    refinements: u8,
    side: u8,
    reach: u8,
    scratch_delta: i8,
}

/// The decoded input, for reading a crash.
pub fn show(data: &[u8]) -> String {
    super::show::<Input>(data)
}

pub fn run(data: &[u8]) {
    let Some(input) = super::decode::<Input>(data) else {
        return;
    };
    // Up to 48 x 48: the outline labels every pixel of its area, several times per candidate.
    let (w, h) = (
        usize::from(input.scene.width % 48) + 1,
        usize::from(input.scene.height % 48) + 1,
    );
    let frames: Vec<Frame> = (0..=input.moves.len().min(3))
        .map(|k| frame(&input, k, (w, h)))
        .collect();

    let dense_params = DenseParams {
        cell: usize::from(input.cell % 13) + 4,
        lk: kestrel::lk::LkParams {
            window: usize::from(input.window % 12) * 2 + 3,
            max_level: usize::from(input.max_level % 4),
            ..DenseParams::for_motion().lk
        },
        ..DenseParams::for_motion()
    };
    let Ok(dense) = DenseFlow::new(dense_params) else {
        return;
    };
    let Ok(layout) = dense.layout(w, h) else {
        return;
    };
    let motion = MotionParams {
        threshold: input.threshold,
        boxes: BoxRules {
            min_nodes: u32::from(input.min_nodes % 4),
            ..BoxRules::default()
        },
        ..MotionParams::default()
    };
    let Ok(detector) = MotionDetector::new(motion) else {
        assert!(!(motion.threshold.is_finite() && motion.threshold >= 0.0));
        return;
    };
    let outline = input.outline.as_ref().map(|o| {
        let params = OutlineParams {
            margin: usize::from(o.margin % 16),
            min_gain: o.min_gain % 64,
            min_pixels: usize::from(o.min_pixels),
            refinements: usize::from(o.refinements % 4),
            // 0 to 99: below OUTLINE_MIN_SIDE is refused.
            side: usize::from(o.side % 100),
            reach: usize::from(o.reach % 24),
        };
        let scratch = outline_scratch_len(params.side, params.reach)
            .saturating_add_signed(o.scratch_delta.into());
        (params, scratch)
    });
    let outliner = match outline {
        Some((params, scratch)) => match Outliner::new(params) {
            Ok(outliner) => Some((outliner, scratch)),
            Err(e) => {
                let side = !(8..=255).contains(&params.side);
                let (field, bound) = if side {
                    ("side", Bound::Range { min: 8, max: 255 })
                } else {
                    ("reach", Bound::AtMost(128))
                };
                assert_eq!(e, ConfigError { field, bound });
                assert!(side || params.reach > 128);
                return;
            }
        },
        None => None,
    };
    let mut pipeline = Pipeline {
        dense,
        layout,
        detector,
        fit: DominantFitParams::default(),
        outliner,
        persistence: BoxPersistence::new(input.persist_pairs % 4),
        nodes: vec![GridNode::EMPTY; layout.len()],
        boxes: usize::from(input.boxes % 12),
        pairs: 0,
    };
    // The grid searches down to the LK's coarsest level, which must hold half a window.
    let too_small = |fw: usize, fh: usize| {
        let top = dense_params.lk.max_level;
        level_size(fw, top).min(level_size(fh, top)) <= dense_params.lk.window / 2
    };
    // Level 1 at least: the outline's vote needs it.
    let levels = dense_params.lk.max_level.max(1);
    let mut prev: Option<Frame> = None;
    for next in frames {
        // A buffer cut short is refused by the view, before the pipeline sees it.
        let Some(next_view) = next.view() else {
            continue;
        };
        let Some(prev_view) = prev.as_ref().and_then(Frame::view) else {
            prev = Some(next);
            continue;
        };
        let refused = (prev_view.width(), prev_view.height()) != (next.width, next.height);
        let mut prev_storage = vec![0; pyramid_storage_len(w, h, levels)];
        let mut next_storage = vec![0; pyramid_storage_len(next.width, next.height, levels)];
        let prev_pyramid = Pyramid::build(prev_view, levels, &mut prev_storage).expect("pyramid");
        let next_pyramid = Pyramid::build(next_view, levels, &mut next_storage).expect("pyramid");
        let small = too_small(w, h) || too_small(next.width, next.height);
        match pipeline.pair(&prev_pyramid, &next_pyramid) {
            // A refused frame changes nothing: the pair after it starts from the frame before.
            Err(e) => {
                let documented = match e {
                    DenseError::FrameSizeMismatch => refused,
                    DenseError::FrameTooSmall => small,
                    _ => false,
                };
                assert!(
                    documented,
                    "{e:?}: frames {w}x{h} and {}x{}",
                    next.width, next.height
                );
            }
            Ok(()) => {
                assert!(
                    !refused && !small,
                    "frames of two sizes, or too small, taken"
                );
                prev = Some(next);
            }
        }
    }
}

/// Frame `k` of the sequence: the scene under the `k`th change, the mover pasted over it.
fn frame(input: &Input, k: usize, (w, h): (usize, usize)) -> Frame {
    let resized = usize::from(input.resized % 8) == k && k > 0;
    let (w, h) = if resized { (w + 3, h) } else { (w, h) };
    let change = k
        .checked_sub(1)
        .and_then(|i| input.moves.get(i))
        .copied()
        .unwrap_or(input.scene.change);
    let mut frame = Picture {
        change,
        ..input.scene.clone()
    }
    .render_at(w, h);
    if let Some(m) = &input.mover {
        let object = m.picture.render_at(w, h);
        let side = usize::from(m.side % 24) + 1;
        let step = |start: u8, v: i8| {
            i64::from(start % 48).saturating_add(i64::from(v % 4).saturating_mul(k as i64))
        };
        let (x0, y0) = (step(m.x, m.vx), step(m.y, m.vy));
        for y in 0..h {
            for x in 0..w {
                let inside = |p: usize, p0: i64| (p0..p0 + side as i64).contains(&(p as i64));
                if inside(x, x0) && inside(y, y0) {
                    if let (Some(&v), Some(p)) = (
                        object.pixels.get(y * object.stride + x),
                        frame.pixels.get_mut(y * frame.stride + x),
                    ) {
                        *p = v;
                    }
                }
            }
        }
    }
    frame
}

/// The stages of `host-sim motion`, with the buffers of one frame size.
struct Pipeline {
    dense: DenseFlow,
    layout: GridLayout,
    detector: MotionDetector,
    fit: DominantFitParams,
    outliner: Option<(Outliner, usize)>,
    persistence: BoxPersistence<REMEMBERED>,
    nodes: Vec<GridNode>,
    boxes: usize,
    /// Pairs taken so far.
    pairs: usize,
}

impl Pipeline {
    fn pair(&mut self, prev: &Pyramid<'_>, next: &Pyramid<'_>) -> Result<(), DenseError> {
        let layout = self.layout;
        let (w, h) = (layout.width(), layout.height());
        let mut scratch = vec![0; scratch_len(self.dense.params().lk.window)];
        self.dense
            .compute(prev, next, &mut self.nodes, &mut scratch)?;
        let camera = DominantMotion::fit(&layout, &self.nodes, &self.fit).expect("fit");
        let mut mask = vec![0; mask_words(w, h, layout.cell())];
        let mut motion_scratch = vec![0; motion_scratch_len(w, h, layout.cell())];
        let mut boxes = vec![MotionBox::default(); self.boxes];
        let summary = self
            .detector
            .detect(
                &layout,
                &self.nodes,
                &camera.motion,
                &mut mask,
                &mut motion_scratch,
                &mut boxes,
            )
            .expect("buffers of the documented lengths");
        let mut candidates = summary.boxes;
        assert!(candidates <= boxes.len());
        if let Some((outliner, scratch_len)) = &self.outliner {
            let expected = self.persistence.append_expected(&mut boxes, candidates);
            assert!(candidates <= expected && expected <= boxes.len());
            let mut scratch = vec![0u16; *scratch_len];
            let mut outlines = vec![MotionBox::default(); self.boxes];
            let found = outliner.outline(
                prev,
                next,
                &camera.motion,
                &layout,
                &self.nodes,
                &mask,
                &boxes[..expected],
                &mut scratch,
                &mut outlines,
            );
            let needed = outline_scratch_len(outliner.params().side, outliner.params().reach);
            match found {
                Err(e) => {
                    let short = ConfigError {
                        field: "scratch",
                        bound: Bound::MinLen(needed),
                    };
                    assert_eq!(e, DenseError::Config(short));
                    assert!(*scratch_len < needed, "valid scratch refused");
                    return Ok(());
                }
                Ok(n) => {
                    assert!(*scratch_len >= needed, "short scratch taken");
                    assert!(n <= outlines.len());
                    for b in &outlines[..n] {
                        check_box(b, w, h);
                    }
                    candidates = n;
                    boxes = outlines;
                }
            }
        }
        let before = boxes.clone();
        let kept = self.persistence.confirm(&layout, &mut boxes, candidates);
        assert!(kept <= candidates.min(boxes.len()));
        // The kept boxes are the candidates' own, in their order.
        let mut from = before[..candidates.min(before.len())].iter();
        for b in &boxes[..kept] {
            check_box(b, w, h);
            assert!(from.any(|c| c == b), "a confirmed box no candidate gave");
        }
        if self.pairs == 0 && self.persistence.min_pairs() >= 2 {
            assert_eq!(kept, 0, "a box confirmed on the first pair");
        }
        self.pairs += 1;
        Ok(())
    }
}

/// A box with pixels, inside the `w` x `h` frame, as is the place it moves to in the next.
fn check_box(b: &MotionBox, w: usize, h: usize) {
    assert!(b.w > 0 && b.h > 0, "{b:?}");
    assert!(usize::from(b.x) + usize::from(b.w) <= w, "{b:?}");
    assert!(usize::from(b.y) + usize::from(b.h) <= h, "{b:?}");
    assert!(b.mean_flow.x.to_num::<f32>().is_finite(), "{b:?}");
    let moved = b.in_next_frame(w, h);
    assert!(
        usize::from(moved.x) + usize::from(moved.w) <= w,
        "{moved:?}"
    );
    assert!(
        usize::from(moved.y) + usize::from(moved.h) <= h,
        "{moved:?}"
    );
}

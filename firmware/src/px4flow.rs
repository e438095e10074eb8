//! The baseline: PX4FLOW's block matching (the `px4flow` crate, its defaults: ±4 px search,
//! SADs by USADA8) on every consecutive frame pair of the sequence, after the profile.
//!
//! The instructions include copying the two 64x64 crops into the matcher's workspace (PX4FLOW's
//! camera delivers its 64x64 image directly).
//!
//! Prints one line: `px4flow instructions_per_frame=N flow_x=X flow_y=Y flow_error_px=E
//! quality=Q pairs=P valid_blocks=V`, with the mean instructions of one `BlockMatcher::flow`
//! call per pair, the mean flow over the pairs, the worst pair's distance from the camera's
//! motion (px, Euclidean), the lowest quality and the fewest valid blocks of any pair.
//! PX4FLOW matches the central 64x64 pixels, which the moving object crosses, and averages
//! every valid block, the object's too. Reported, never checked.

use cortex_m_semihosting::hprintln;
use kestrel::ImageView;
// The crate, not this module.
use ::px4flow::{BlockMatcher, Config, Error, Flow, Workspace};

use crate::camera;
use crate::checks::sqrt;
use crate::meter::{instructions, Meter, Ticks};
use crate::report::Milli;
use crate::scene::{FRAMES, HEIGHT, MOTION_MILLIPX, WIDTH};

/// Runs the baseline on frames (0, 1), (1, 2), ... and prints its line.
#[inline(never)]
pub fn run(meter: &Meter) {
    let config = Config::default();
    let Ok(matcher) = BlockMatcher::new(config) else {
        hprintln!("error px4flow: the default settings were refused");
        return;
    };
    // The two 64x64 crops, on the stack: the run is over, and a static would count in the
    // pipeline's RAM figures.
    let mut workspace = Workspace::new();
    let truth = (
        MOTION_MILLIPX.0 as f32 / 1000.0,
        MOTION_MILLIPX.1 as f32 / 1000.0,
    );
    let mut ticks = Ticks::default();
    let mut sum = (0.0f32, 0.0f32);
    let mut worst_error = 0.0f32;
    let mut min_quality = u8::MAX;
    let mut min_valid = u8::MAX;
    let pairs = FRAMES - 1;
    for k in 1..FRAMES {
        let views = (
            ImageView::packed(camera::frame(k - 1), WIDTH, HEIGHT),
            ImageView::packed(camera::frame(k), WIDTH, HEIGHT),
        );
        let (Ok(prev), Ok(next)) = views else {
            hprintln!("error px4flow: frame {} is missing", k);
            return;
        };
        let (result, pair_ticks) = meter.measure(|| flow(&matcher, &prev, &next, &mut workspace));
        let flow: Flow = match result {
            Ok(flow) => flow,
            Err(e) => {
                hprintln!("error px4flow: pair {}: {:?}", k, e);
                return;
            }
        };
        ticks += pair_ticks;
        sum = (sum.0 + flow.x, sum.1 + flow.y);
        let (ex, ey) = (flow.x - truth.0, flow.y - truth.1);
        worst_error = worst_error.max(sqrt(ex * ex + ey * ey));
        min_quality = min_quality.min(flow.quality);
        min_valid = min_valid.min(flow.valid_blocks);
    }
    let n = pairs as f32;
    hprintln!(
        "px4flow instructions_per_frame={} flow_x={} flow_y={} flow_error_px={} quality={} \
         pairs={} valid_blocks={} search_radius={}",
        instructions(ticks) / pairs as u64,
        Milli(sum.0 / n),
        Milli(sum.1 / n),
        Milli(worst_error),
        min_quality,
        pairs,
        min_valid,
        config.search_radius,
    );
}

/// One call of the matcher, kept out of line: inlined into `run`, the workspace would sit at a
/// fixed offset of this stack frame beyond the reach of Thumb's 12-bit load offsets, and every
/// pixel load would take an extra instruction to form its address.
#[inline(never)]
fn flow(
    matcher: &BlockMatcher,
    prev: &ImageView<'_>,
    next: &ImageView<'_>,
    workspace: &mut Workspace,
) -> Result<Flow, Error> {
    matcher.flow(prev, next, workspace)
}

//! The RAM each part of the pipeline holds between frames, from the buffers' sizes.

use core::mem::size_of;

use cortex_m_semihosting::hprintln;
use kestrel::dense::GridNode;
use kestrel::detect::Corner;

use crate::dense::{Dense, MASK_WORDS, MOTION_SCRATCH_LEN, NODES};
use crate::ego::Ego;
use crate::pipeline::{
    FrameTracker, Pipeline, CANDIDATES, DETECT_SCRATCH_LEN, LK_SCRATCH_LEN, STORAGE_LEN,
};

/// The tracker's state: both pyramids (and FAST's rows), LK and detector scratch, candidates,
/// and the tracker itself (tracks and their birth patches).
pub const fn tracker_state() -> usize {
    STORAGE_LEN
        + LK_SCRATCH_LEN * size_of::<i16>()
        + DETECT_SCRATCH_LEN * size_of::<i32>()
        + CANDIDATES * size_of::<Corner>()
        + size_of::<FrameTracker>()
}

/// The dense grid's state: nodes, its LK scratch, mask, motion scratch, detector and boxes.
pub const fn dense_state() -> usize {
    NODES * size_of::<GridNode>()
        + LK_SCRATCH_LEN * size_of::<i16>()
        + (MASK_WORDS + MOTION_SCRATCH_LEN) * size_of::<u32>()
        + size_of::<Dense>()
}

/// Prints the sizes.
pub fn print() {
    hprintln!(
        "memory tracker_state={} tracker_storage={} tracker_struct={} dense_state={} \
         ego_state={} pipeline_struct={}",
        tracker_state(),
        STORAGE_LEN,
        size_of::<FrameTracker>(),
        dense_state(),
        size_of::<Ego>(),
        size_of::<Pipeline>(),
    );
}

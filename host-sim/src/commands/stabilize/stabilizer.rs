//! Video stabilization: remove the camera's shake, keep its intended motion.
//!
//! The frame-to-frame homographies are chained into the camera path `C_k` (frame 0 to frame
//! `k`); its similarity parameters about the frame centre (shift, rotation, log scale) are
//! smoothed by a centred moving average; and each frame is warped so that it shows the view of
//! the smoothed path: output pixel `x` takes frame `k` at `C_k(S_k⁻¹(x))`, bilinearly, black
//! outside the frame. A steady pan, turn or zoom is linear in these parameters, so the average
//! leaves it untouched and only the shake is removed.
//!
//! [`Stabilizer`] streams: frame `k` is written as soon as the path is known `radius` frames
//! ahead of it, so memory holds `radius + 1` frames whatever the length of the video. The
//! averaging window is kept symmetric about each frame, shrinking near both ends of the
//! sequence, so the first and last frames are never pulled towards one side.

use super::path::PathPoint;
use super::warp::warp_bilinear;

use std::collections::VecDeque;

use crate::synth::Homography;
use crate::Frame;

/// Chains frame-to-frame motion, smooths the path and returns stabilized frames in order.
#[derive(Debug)]
pub struct Stabilizer {
    radius: usize,
    centre: (f64, f64),
    /// `C_k` and its parameters for every frame so far.
    path: Vec<(Homography, PathPoint)>,
    /// Frames not yet written, with their index.
    waiting: VecDeque<(usize, Frame)>,
}

impl Stabilizer {
    /// A stabilizer averaging the path over `2 radius + 1` frames of `width` x `height`.
    pub fn new(radius: usize, width: usize, height: usize) -> Self {
        Self {
            radius,
            centre: ((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0),
            path: Vec::new(),
            waiting: VecDeque::new(),
        }
    }

    /// Takes the next frame and the motion from the previous frame to it (ignored for the
    /// first frame); returns the frames that can now be stabilized, with their index.
    pub fn push(&mut self, frame: Frame, motion: &Homography) -> Vec<(usize, Frame)> {
        let camera = match self.path.last() {
            Some((previous, _)) => previous.then(motion),
            None => Homography::IDENTITY,
        };
        let previous_angle = self.path.last().map(|(_, p)| p.angle);
        let point = PathPoint::of(&camera, self.centre, previous_angle);
        self.path.push((camera, point));
        self.waiting.push_back((self.path.len() - 1, frame));
        let mut ready = Vec::new();
        while let Some(&(k, _)) = self.waiting.front() {
            if k + self.radius >= self.path.len() {
                break;
            }
            ready.push(self.stabilize_front(k + self.radius));
        }
        ready
    }

    /// Stabilizes every frame still waiting, taking the last frame pushed as the end of the
    /// sequence.
    pub fn finish(mut self) -> Vec<(usize, Frame)> {
        let last = self.path.len().saturating_sub(1);
        let mut ready = Vec::new();
        while !self.waiting.is_empty() {
            ready.push(self.stabilize_front(last));
        }
        ready
    }

    /// Warps the oldest waiting frame; the path is known up to frame `last`.
    fn stabilize_front(&mut self, last: usize) -> (usize, Frame) {
        let (k, frame) = self.waiting.pop_front().expect("a frame is waiting");
        let radius = self.radius.min(k).min(last - k);
        let window = &self.path[k - radius..=k + radius];
        let smooth = PathPoint::mean(window.iter().map(|(_, p)| p)).similarity(self.centre);
        let camera = &self.path[k].0;
        // Output pixel -> smoothed view -> frame 0 -> frame k.
        let correction = smooth
            .inverse()
            .map(|back| back.then(camera))
            .unwrap_or(Homography::IDENTITY);
        (k, warp_bilinear(&frame, &correction))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(value: u8) -> Frame {
        Frame::filled(8, 6, value)
    }

    #[test]
    fn frames_come_out_in_order_once_the_path_ahead_is_known() {
        let mut stabilizer = Stabilizer::new(2, 8, 6);
        let step = Homography::translation(0.5, 0.0);
        let mut out = Vec::new();
        for k in 0..5 {
            let ready = stabilizer.push(frame(k), &step);
            // Frame k is ready when frame k + 2 has arrived.
            assert_eq!(ready.len(), usize::from(k >= 2), "{k}");
            out.extend(ready);
        }
        out.extend(stabilizer.finish());
        let order: Vec<usize> = out.iter().map(|(k, _)| *k).collect();
        assert_eq!(order, [0, 1, 2, 3, 4]);
    }

    #[test]
    fn a_steady_pan_is_left_alone() {
        let mut stabilizer = Stabilizer::new(3, 8, 6);
        let step = Homography::translation(0.75, -0.25);
        let textured = Frame {
            width: 8,
            height: 6,
            data: (0..48).map(|i| (i * 5) as u8).collect(),
        };
        let mut out = Vec::new();
        for _ in 0..7 {
            out.extend(stabilizer.push(textured.clone(), &step));
        }
        out.extend(stabilizer.finish());
        assert!(out.iter().all(|(_, f)| *f == textured));
    }
}

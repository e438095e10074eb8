//! Track trails: the last few positions of every live track, drawn as fading coloured lines
//! ending in a dot, one colour per id.

use std::collections::{BTreeMap, VecDeque};

use image::{Rgb, RgbImage};
use kestrel::track::Track;

use super::canvas;
use crate::Frame;

/// Positions kept per track: the current one and the nine before it.
pub const TRAIL_LEN: usize = 10;

/// How much of its brightness the grey background keeps, so that the trails stand out.
const BACKGROUND: u32 = 180;

/// Radius of the dot on a track's current position, px.
const DOT_RADIUS: f32 = 1.6;

/// The recent positions of the live tracks, by id.
#[derive(Debug, Clone, Default)]
pub struct Trails {
    paths: BTreeMap<u32, VecDeque<(f32, f32)>>,
}

impl Trails {
    /// No trails yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Moves on to a frame whose live tracks are `tracks`: their positions are appended, the
    /// trails of tracks that ended are forgotten.
    pub fn update(&mut self, tracks: &[Track]) {
        let mut next = BTreeMap::new();
        for track in tracks {
            let mut path = self.paths.remove(&track.id).unwrap_or_default();
            if path.len() == TRAIL_LEN {
                path.pop_front();
            }
            path.push_back((track.position.x.to_num(), track.position.y.to_num()));
            next.insert(track.id, path);
        }
        self.paths = next;
    }

    /// The number of live trails.
    pub fn len(&self) -> usize {
        self.paths.len()
    }

    /// True when no track is live.
    pub fn is_empty(&self) -> bool {
        self.paths.is_empty()
    }

    /// `frame` with every trail drawn over it: older segments fainter, a dot on the current
    /// position.
    pub fn draw(&self, frame: &Frame) -> RgbImage {
        let mut picture = canvas::grey(frame, BACKGROUND);
        for (&id, path) in &self.paths {
            let colour = id_colour(id);
            let segments = path.len().saturating_sub(1);
            for (i, (a, b)) in path.iter().zip(path.iter().skip(1)).enumerate() {
                // The newest segment is opaque, the oldest a quarter.
                let alpha = 0.25 + 0.75 * (i + 1) as f32 / segments as f32;
                canvas::line(&mut picture, *a, *b, colour, alpha);
            }
            if let Some(&current) = path.back() {
                canvas::dot(&mut picture, current, DOT_RADIUS, colour);
            }
        }
        picture
    }
}

/// A bright colour for track `id`: hues spread by the golden ratio, so that tracks born
/// together get clearly different colours.
pub fn id_colour(id: u32) -> Rgb<u8> {
    const GOLDEN: f64 = 0.618_033_988_749_895;
    let hue = (f64::from(id) * GOLDEN).fract() * 6.0;
    let (saturation, value) = (0.8, 1.0);
    let sector = hue.floor();
    let f = hue - sector;
    let (p, q, t) = (
        value * (1.0 - saturation),
        value * (1.0 - saturation * f),
        value * (1.0 - saturation * (1.0 - f)),
    );
    let (r, g, b) = match sector as u8 {
        0 => (value, t, p),
        1 => (q, value, p),
        2 => (p, value, t),
        3 => (p, q, value),
        4 => (t, p, value),
        _ => (value, p, q),
    };
    let byte = |v: f64| (v * 255.0).round() as u8;
    Rgb([byte(r), byte(g), byte(b)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel::Point;

    fn track(id: u32, x: f32, y: f32) -> Track {
        Track {
            id,
            position: Point::from_f32(x, y),
            previous: Point::from_f32(x, y),
            ..Track::default()
        }
    }

    #[test]
    fn trails_keep_the_last_positions_of_live_tracks() {
        let mut trails = Trails::new();
        for k in 0..15 {
            let mut tracks = vec![track(1, k as f32, 5.0)];
            if k < 3 {
                tracks.push(track(2, 3.0, k as f32));
            }
            trails.update(&tracks);
        }
        assert_eq!(trails.len(), 1);
        let path = &trails.paths[&1];
        assert_eq!(path.len(), TRAIL_LEN);
        assert_eq!(path.front(), Some(&(5.0, 5.0)));
        assert_eq!(path.back(), Some(&(14.0, 5.0)));
    }

    #[test]
    fn drawing_marks_the_trail_and_the_point() {
        let mut trails = Trails::new();
        for x in [4.0, 8.0, 12.0] {
            trails.update(&[track(7, x, 10.0)]);
        }
        let image = trails.draw(&Frame::filled(20, 20, 0));
        let colour = id_colour(7);
        assert_eq!(*image.get_pixel(12, 10), colour);
        // The oldest segment is fainter than the newest.
        let brightness = |x: u32| {
            image
                .get_pixel(x, 10)
                .0
                .iter()
                .map(|&c| u32::from(c))
                .sum::<u32>()
        };
        assert!(0 < brightness(5) && brightness(5) < brightness(9));
        assert_eq!(image.get_pixel(0, 0).0, [0, 0, 0]);
    }

    #[test]
    fn neighbouring_ids_get_different_colours() {
        for id in 0..50 {
            let (a, b) = (id_colour(id).0, id_colour(id + 1).0);
            let distance: i32 = a
                .iter()
                .zip(&b)
                .map(|(&x, &y)| (i32::from(x) - i32::from(y)).abs())
                .sum();
            assert!(distance > 60, "{id}: {a:?} {b:?}");
        }
    }
}

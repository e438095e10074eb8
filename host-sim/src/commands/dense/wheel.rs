//! The Middlebury colour code for flow (Baker et al., "A Database and Evaluation Methodology
//! for Optical Flow", 2011), as in its reference `colorcode.cpp`.
//!
//! Hue is the flow's direction, read off a wheel of 55 colours built from six ramps (red to
//! yellow 15, yellow to green 6, green to cyan 4, cyan to blue 11, blue to magenta 13, magenta
//! to red 6); saturation grows with speed, normalised by the largest speed in the picture, from
//! white at rest to the full colour at the largest speed. Unknown flow is black. A legend wheel
//! in the top-right corner shows the colour of every direction and speed up to that largest.

use super::field::FlowField;
use image::{Rgb, RgbImage};

/// The lengths of the six ramps of the wheel: RY, YG, GC, CB, BM, MR.
pub const RAMPS: [usize; 6] = [15, 6, 4, 11, 13, 6];
/// Colours on the wheel.
pub const WHEEL_LEN: usize = 55;

/// The wheel's colours, red first, turning through yellow, green, cyan, blue and magenta.
pub fn colour_wheel() -> [[u8; 3]; WHEEL_LEN] {
    let mut wheel = [[0u8; 3]; WHEEL_LEN];
    let mut k = 0;
    // Each ramp holds one channel at 255 and moves another up (or down) in equal steps.
    let ramps: [(usize, usize, bool); 6] = [
        (0, 1, true),  // red held, green rises
        (1, 0, false), // green held, red falls
        (1, 2, true),  // green held, blue rises
        (2, 1, false), // blue held, green falls
        (2, 0, true),  // blue held, red rises
        (0, 2, false), // red held, blue falls
    ];
    for (&len, &(held, moving, rising)) in RAMPS.iter().zip(&ramps) {
        for i in 0..len {
            let step = (255 * i / len) as u8;
            if let Some(colour) = wheel.get_mut(k) {
                colour[held] = 255;
                colour[moving] = if rising { step } else { 255 - step };
            }
            k += 1;
        }
    }
    wheel
}

/// The colour of flow (`u`, `v`) already divided by the largest speed: direction gives the
/// hue; saturation grows with the speed up to 1, beyond which the colour darkens.
pub fn flow_colour(wheel: &[[u8; 3]; WHEEL_LEN], u: f32, v: f32) -> [u8; 3] {
    let radius = u.hypot(v);
    let angle = (-v).atan2(-u) / std::f32::consts::PI;
    let fk = (angle + 1.0) / 2.0 * (WHEEL_LEN - 1) as f32;
    let k0 = (fk as usize).min(WHEEL_LEN - 1);
    let k1 = (k0 + 1) % WHEEL_LEN;
    let f = fk - k0 as f32;
    std::array::from_fn(|c| {
        let c0 = f32::from(wheel[k0][c]) / 255.0;
        let c1 = f32::from(wheel[k1][c]) / 255.0;
        let mixed = (1.0 - f) * c0 + f * c1;
        let shaded = if radius <= 1.0 {
            1.0 - radius * (1.0 - mixed)
        } else {
            mixed * 0.75
        };
        (255.0 * shaded) as u8
    })
}

/// The colour-coded picture of `field`, with the legend wheel.
pub fn flow_picture(field: &FlowField) -> RgbImage {
    let wheel = colour_wheel();
    let scale = field.max_speed().max(f32::EPSILON);
    let mut picture = RgbImage::from_fn(field.width as u32, field.height as u32, |x, y| {
        let flow = field.at(x as usize, y as usize);
        Rgb(flow.map_or([0, 0, 0], |(u, v)| {
            flow_colour(&wheel, u / scale, v / scale)
        }))
    });
    draw_legend(&mut picture, &wheel);
    picture
}

/// Draws the legend: a disc in the top-right corner coloured by the flow each of its points
/// stands for (the rim is the largest speed), ringed in black.
fn draw_legend(picture: &mut RgbImage, wheel: &[[u8; 3]; WHEEL_LEN]) {
    let radius = (picture.width().min(picture.height()) / 10).max(6) as f32;
    let margin = 2.0;
    let centre = (
        picture.width() as f32 - margin - radius - 1.0,
        margin + radius + 1.0,
    );
    let mut set = |x: f32, y: f32, colour| {
        if let Some(p) = picture.get_pixel_mut_checked(x as u32, y as u32) {
            *p = Rgb(colour);
        }
    };
    let reach = radius as i64 + 2;
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let (x, y) = (centre.0 + dx as f32, centre.1 + dy as f32);
            if x < 0.0 || y < 0.0 {
                continue;
            }
            let (u, v) = (dx as f32 / radius, dy as f32 / radius);
            let r = u.hypot(v);
            if r <= 1.0 {
                set(x, y, flow_colour(wheel, u, v));
            } else if r <= 1.0 + 1.5 / radius {
                set(x, y, [0, 0, 0]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wheel_turns_from_red_through_the_primaries() {
        let wheel = colour_wheel();
        assert_eq!(wheel[0], [255, 0, 0]);
        assert_eq!(wheel[15], [255, 255, 0]);
        assert_eq!(wheel[21], [0, 255, 0]);
        assert_eq!(wheel[25], [0, 255, 255]);
        assert_eq!(wheel[36], [0, 0, 255]);
        assert_eq!(wheel[49], [255, 0, 255]);
        assert_eq!(wheel[54], [255, 0, 43]);
    }

    #[test]
    fn rest_is_white_and_directions_match_the_reference() {
        let wheel = colour_wheel();
        assert_eq!(flow_colour(&wheel, 0.0, 0.0), [255, 255, 255]);
        // As in the Middlebury key: right is red, left cyan-blue, down (v > 0) orange-yellow,
        // up blue-violet.
        let right = flow_colour(&wheel, 1.0, 0.0);
        assert!(
            right[0] == 255 && right[1] == 0 && right[2] < 50,
            "{right:?}"
        );
        let left = flow_colour(&wheel, -1.0, 0.0);
        assert!(left[0] == 0 && left[1] > 150 && left[2] == 255, "{left:?}");
        let down = flow_colour(&wheel, 0.0, 1.0);
        assert!(down[0] == 255 && down[1] > 200 && down[2] == 0, "{down:?}");
        let up = flow_colour(&wheel, 0.0, -1.0);
        assert!(up[0] > 50 && up[1] == 0 && up[2] == 255, "{up:?}");
        // Beyond the largest speed the colour darkens.
        let fast = flow_colour(&wheel, 2.0, 0.0);
        assert!(fast[0] == 191 && fast[1] == 0, "{fast:?}");
    }

    #[test]
    fn unknown_is_black_and_the_legend_is_drawn() {
        let field = FlowField {
            width: 40,
            height: 30,
            flow: vec![None; 1200],
        };
        let picture = flow_picture(&field);
        assert_eq!(picture.get_pixel(0, 29).0, [0, 0, 0]);
        // The legend's centre is white (no motion).
        let radius = 6.0f32;
        let centre = (
            (40.0 - 2.0 - radius - 1.0) as u32,
            (2.0 + radius + 1.0) as u32,
        );
        assert_eq!(picture.get_pixel(centre.0, centre.1).0, [255, 255, 255]);
    }
}

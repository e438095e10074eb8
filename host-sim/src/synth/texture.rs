//! Procedural textures: a continuous grey-level function of the plane, fixed by a seed.
//!
//! A texture is the sum of
//! - value noise at four octaves (wavelengths 64 to 5 px), the fine detail that LK tracks;
//! - a few random-phase sinusoids, for periodic structure;
//! - a low-frequency contrast mask over those two, so that some regions are nearly flat;
//! - Gaussian blobs and sharp-edged discs and rectangles, for corners and step edges.
//!
//! Every component is smooth at the pixel scale except the shapes' edges, which are one-pixel
//! ramps: as sharp as a good lens makes them, and band-limited enough that area sampling on a
//! 2 x 2 grid per pixel renders them without aliasing.

use super::rng::{lattice, SplitMix64};

/// Mean grey level: dark enough that a gain of 1.25 plus a bias of 15 rarely saturates.
const BASE: f64 = 100.0;
/// Value-noise octaves: (wavelength px, amplitude grey levels).
const OCTAVES: [(f64, f64); 4] = [(64.0, 60.0), (24.0, 50.0), (10.0, 40.0), (5.0, 20.0)];
/// Wavelength of the contrast mask, px.
const MASK_WAVELENGTH: f64 = 90.0;
/// Mask noise values mapped to zero and full contrast (smoothstep between).
const MASK_EDGES: (f64, f64) = (0.3, 0.55);
/// Sinusoids: count, wavelength range px, amplitude range grey levels.
const WAVES: usize = 2;
const WAVE_LENGTHS: (f64, f64) = (7.0, 30.0);
const WAVE_AMPLITUDES: (f64, f64) = (2.0, 6.0);
/// Area per blob and per shape, px² (the densities).
const AREA_PER_BLOB: f64 = 2000.0;
const AREA_PER_SHAPE: f64 = 2500.0;
/// Width of the shapes' edges, px: a step blurred over one pixel, as by a sharp lens. Narrower
/// edges would alias unless rendered with many samples per pixel.
const EDGE: f64 = 1.0;
/// Side of the cells that index blobs and shapes by position, px.
const CELL: f64 = 32.0;

/// An axis-aligned rectangle of the plane, px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    /// Smallest x.
    pub left: f64,
    /// Smallest y.
    pub top: f64,
    /// Largest x.
    pub right: f64,
    /// Largest y.
    pub bottom: f64,
}

impl Extent {
    /// The frame `[0, width] x [0, height]` grown by `margin` on every side.
    pub fn around_frame(width: usize, height: usize, margin: f64) -> Self {
        Self {
            left: -margin,
            top: -margin,
            right: width as f64 + margin,
            bottom: height as f64 + margin,
        }
    }

    /// The smallest extent holding every one of `points`, grown by `margin` on every side.
    ///
    /// ```
    /// use host_sim::synth::Extent;
    /// let extent = Extent::enclosing([(1.0, 5.0), (-2.0, 3.0)].into_iter(), 0.5);
    /// assert_eq!((extent.left, extent.top, extent.right, extent.bottom), (-2.5, 2.5, 1.5, 5.5));
    /// ```
    pub fn enclosing(points: impl Iterator<Item = (f64, f64)>, margin: f64) -> Self {
        let empty = Self {
            left: f64::INFINITY,
            top: f64::INFINITY,
            right: f64::NEG_INFINITY,
            bottom: f64::NEG_INFINITY,
        };
        let tight = points.fold(empty, |e, (x, y)| Self {
            left: e.left.min(x),
            top: e.top.min(y),
            right: e.right.max(x),
            bottom: e.bottom.max(y),
        });
        Self {
            left: tight.left - margin,
            top: tight.top - margin,
            right: tight.right + margin,
            bottom: tight.bottom + margin,
        }
    }

    /// Its width, px.
    pub fn width(&self) -> f64 {
        self.right - self.left
    }

    /// Its height, px.
    pub fn height(&self) -> f64 {
        self.bottom - self.top
    }

    fn random_point(&self, rng: &mut SplitMix64) -> (f64, f64) {
        (
            rng.uniform(self.left, self.right),
            rng.uniform(self.top, self.bottom),
        )
    }
}

/// A seeded procedural texture. Blobs and shapes are scattered over the extent it was made for;
/// noise and sinusoids cover the whole plane.
#[derive(Debug, Clone)]
pub struct Texture {
    octaves: [Octave; OCTAVES.len()],
    /// The contrast mask; `None` keeps full contrast everywhere.
    mask: Option<Octave>,
    waves: Vec<Wave>,
    features: FeatureIndex,
}

impl Texture {
    /// The texture of `seed`, with blobs and shapes over `extent`.
    pub fn random(seed: u64, extent: Extent) -> Self {
        let mut rng = SplitMix64::substream(seed, 0);
        let waves = (0..WAVES).map(|_| Wave::random(&mut rng)).collect();
        let area = extent.width() * extent.height();
        let blobs = (area / AREA_PER_BLOB) as usize;
        let shapes = (area / AREA_PER_SHAPE) as usize;
        let mut features: Vec<Feature> = (0..blobs)
            .map(|_| Feature::blob(extent.random_point(&mut rng), &mut rng))
            .collect();
        features
            .extend((0..shapes).map(|_| Feature::shape(extent.random_point(&mut rng), &mut rng)));
        let octaves =
            OCTAVES.map(|(wavelength, amplitude)| Octave::random(&mut rng, wavelength, amplitude));
        let mask = Some(Octave::random(&mut rng, MASK_WAVELENGTH, 1.0));
        Self {
            octaves,
            mask,
            waves,
            features: FeatureIndex::new(features, extent),
        }
    }

    /// Like [`Texture::random`], without the nearly flat regions: detail at full contrast
    /// everywhere, for small surfaces that must be trackable all over.
    pub fn without_flat_regions(seed: u64, extent: Extent) -> Self {
        Self {
            mask: None,
            ..Self::random(seed, extent)
        }
    }

    /// The grey level at (`u`, `v`): centred on 100, nearly always within 0..255 (rendering
    /// saturates the rest).
    pub fn value(&self, u: f64, v: f64) -> f64 {
        let detail: f64 = self
            .octaves
            .iter()
            .map(|o| o.amplitude * (2.0 * o.value(u, v) - 1.0))
            .chain(self.waves.iter().map(|w| w.value(u, v)))
            .sum();
        BASE + self.contrast(u, v) * detail + self.features.value(u, v)
    }

    /// The contrast mask in `[0, 1]`: zero over the nearly flat regions.
    fn contrast(&self, u: f64, v: f64) -> f64 {
        self.mask.as_ref().map_or(1.0, |mask| {
            smoothstep(MASK_EDGES.0, MASK_EDGES.1, mask.value(u, v))
        })
    }
}

/// One octave of value noise: its own seed, scale, and a random rotation and offset of its
/// lattice, so that the lattices of the octaves do not line up into a visible grid.
#[derive(Debug, Clone, Copy)]
struct Octave {
    seed: u64,
    amplitude: f64,
    /// Texture coordinates to lattice coordinates: rotation and scale, then offset.
    axes: [(f64, f64); 2],
    offset: (f64, f64),
}

impl Octave {
    fn random(rng: &mut SplitMix64, wavelength: f64, amplitude: f64) -> Self {
        let (sin, cos) = rng.uniform(0.0, core::f64::consts::TAU).sin_cos();
        let k = 1.0 / wavelength;
        Self {
            seed: rng.next_u64(),
            amplitude,
            axes: [(k * cos, k * sin), (-k * sin, k * cos)],
            offset: (rng.next_f64(), rng.next_f64()),
        }
    }

    /// The noise at (`u`, `v`), in `[0, 1]`.
    fn value(&self, u: f64, v: f64) -> f64 {
        let [a, b] = self.axes;
        let x = a.0 * u + a.1 * v + self.offset.0;
        let y = b.0 * u + b.1 * v + self.offset.1;
        value_noise(self.seed, x, y)
    }
}

/// Value noise in `[0, 1]`: random values on the integer lattice, blended with the quintic fade,
/// whose first two derivatives vanish at lattice points (no visible grid).
pub(super) fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (i, j) = (floor(x), floor(y));
    let (tx, ty) = (fade(x - i as f64), fade(y - j as f64));
    let top = lerp(lattice(seed, i, j), lattice(seed, i + 1, j), tx);
    let bottom = lerp(lattice(seed, i, j + 1), lattice(seed, i + 1, j + 1), tx);
    lerp(top, bottom, ty)
}

/// `x.floor()` as an integer, without the library call that `f64::floor` costs on baseline
/// x86-64 (no SSE4.1); value noise calls it twice per sample and octave.
fn floor(x: f64) -> i64 {
    let truncated = x as i64;
    if (truncated as f64) > x {
        truncated - 1
    } else {
        truncated
    }
}

fn fade(t: f64) -> f64 {
    t * t * t * (t * (6.0 * t - 15.0) + 10.0)
}

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

fn smoothstep(low: f64, high: f64, x: f64) -> f64 {
    let t = ((x - low) / (high - low)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A plane sinusoid with random orientation, wavelength and phase.
#[derive(Debug, Clone, Copy)]
struct Wave {
    /// Wave vector, radians per px.
    k: (f64, f64),
    phase: f64,
    amplitude: f64,
}

impl Wave {
    fn random(rng: &mut SplitMix64) -> Self {
        let angle = rng.uniform(0.0, core::f64::consts::PI);
        let wavelength = rng.uniform(WAVE_LENGTHS.0, WAVE_LENGTHS.1);
        let k = core::f64::consts::TAU / wavelength;
        Self {
            k: (k * angle.cos(), k * angle.sin()),
            phase: rng.uniform(0.0, core::f64::consts::TAU),
            amplitude: rng.uniform(WAVE_AMPLITUDES.0, WAVE_AMPLITUDES.1),
        }
    }

    fn value(&self, u: f64, v: f64) -> f64 {
        self.amplitude * (self.k.0 * u + self.k.1 * v + self.phase).sin()
    }
}

/// The profile of a blob or shape.
#[derive(Debug, Clone, Copy)]
enum Profile {
    /// `exp(-r² / 2σ²)`.
    Gaussian { sigma: f64 },
    /// 1 inside the radius, 0 outside, a ramp of [`EDGE`] px between.
    Disc { radius: f64 },
    /// 1 inside a rectangle of half sides `half`, turned by the angle of (`cos`, `sin`); edges
    /// as the disc's.
    Rectangle {
        half: (f64, f64),
        cos: f64,
        sin: f64,
    },
}

/// A blob or shape added to the texture.
#[derive(Debug, Clone, Copy)]
struct Feature {
    centre: (f64, f64),
    /// Grey levels added at full strength (negative darkens).
    amplitude: f64,
    /// Distance from the centre beyond which the feature adds nothing.
    reach: f64,
    profile: Profile,
}

impl Feature {
    fn blob(centre: (f64, f64), rng: &mut SplitMix64) -> Self {
        let sigma = rng.uniform(1.5, 6.0);
        Self {
            centre,
            amplitude: signed(rng, 25.0, 55.0),
            // exp(-8) ≈ 3e-4: cut there, the step is a few hundredths of a grey level.
            reach: 4.0 * sigma,
            profile: Profile::Gaussian { sigma },
        }
    }

    fn shape(centre: (f64, f64), rng: &mut SplitMix64) -> Self {
        let amplitude = signed(rng, 20.0, 45.0);
        if rng.below(2) == 0 {
            let radius = rng.uniform(3.0, 14.0);
            return Self {
                centre,
                amplitude,
                reach: radius,
                profile: Profile::Disc { radius },
            };
        }
        let half = (rng.uniform(3.0, 16.0), rng.uniform(3.0, 16.0));
        let (sin, cos) = rng.uniform(0.0, core::f64::consts::PI).sin_cos();
        Self {
            centre,
            amplitude,
            reach: half.0.hypot(half.1) + EDGE,
            profile: Profile::Rectangle { half, cos, sin },
        }
    }

    fn value(&self, u: f64, v: f64) -> f64 {
        let (du, dv) = (u - self.centre.0, v - self.centre.1);
        if du * du + dv * dv > self.reach * self.reach {
            return 0.0;
        }
        let strength = match self.profile {
            Profile::Gaussian { sigma } => (-(du * du + dv * dv) / (2.0 * sigma * sigma)).exp(),
            Profile::Disc { radius } => edge(du.hypot(dv) - radius),
            Profile::Rectangle { half, cos, sin } => {
                // Into the rectangle's own axes; the larger excess is the distance to the
                // boundary along the sides (corners come out slightly rounded-off squares).
                let (a, b) = (cos * du + sin * dv, -sin * du + cos * dv);
                edge((a.abs() - half.0).max(b.abs() - half.1))
            }
        };
        self.amplitude * strength
    }
}

/// A shape's strength at signed distance `d` from its boundary (negative inside): 1 inside, 0
/// outside, linear across the [`EDGE`] px wide edge.
fn edge(d: f64) -> f64 {
    (0.5 - d / EDGE).clamp(0.0, 1.0)
}

/// Uniform magnitude in `[low, high)` with a random sign.
fn signed(rng: &mut SplitMix64, low: f64, high: f64) -> f64 {
    let magnitude = rng.uniform(low, high);
    if rng.below(2) == 0 {
        magnitude
    } else {
        -magnitude
    }
}

/// Features indexed by a grid of cells, so that a sample only visits the features that can
/// reach it instead of all of them.
#[derive(Debug, Clone)]
struct FeatureIndex {
    features: Vec<Feature>,
    extent: Extent,
    columns: usize,
    rows: usize,
    /// Per cell, row by row, the indices of the features whose reach overlaps it.
    cells: Vec<Vec<usize>>,
}

impl FeatureIndex {
    fn new(features: Vec<Feature>, extent: Extent) -> Self {
        let columns = (extent.width() / CELL).ceil().max(1.0) as usize;
        let rows = (extent.height() / CELL).ceil().max(1.0) as usize;
        let mut cells = vec![Vec::new(); columns * rows];
        for (i, f) in features.iter().enumerate() {
            let (c0, r0) = Self::cell_of(&extent, f.centre.0 - f.reach, f.centre.1 - f.reach);
            let (c1, r1) = Self::cell_of(&extent, f.centre.0 + f.reach, f.centre.1 + f.reach);
            for r in r0.clamp(0, rows as i64 - 1)..=r1.clamp(0, rows as i64 - 1) {
                for c in c0.clamp(0, columns as i64 - 1)..=c1.clamp(0, columns as i64 - 1) {
                    cells[r as usize * columns + c as usize].push(i);
                }
            }
        }
        Self {
            features,
            extent,
            columns,
            rows,
            cells,
        }
    }

    /// The (unclamped) cell holding (`u`, `v`).
    fn cell_of(extent: &Extent, u: f64, v: f64) -> (i64, i64) {
        (
            ((u - extent.left) / CELL).floor() as i64,
            ((v - extent.top) / CELL).floor() as i64,
        )
    }

    /// The summed contribution of the features at (`u`, `v`).
    ///
    /// Outside the extent the nearest edge cell answers: feature ranges were clamped into the
    /// grid the same way, so it lists every feature that reaches that far.
    fn value(&self, u: f64, v: f64) -> f64 {
        let (c, r) = Self::cell_of(&self.extent, u, v);
        let c = c.clamp(0, self.columns as i64 - 1) as usize;
        let r = r.clamp(0, self.rows as i64 - 1) as usize;
        self.cells[r * self.columns + c]
            .iter()
            .map(|&i| self.features[i].value(u, v))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texture(seed: u64) -> Texture {
        Texture::random(seed, Extent::around_frame(160, 120, 40.0))
    }

    #[test]
    fn the_same_seed_gives_the_same_texture() {
        let (a, b, c) = (texture(3), texture(3), texture(4));
        let points = [(0.0, 0.0), (17.3, 91.25), (-30.0, 140.0), (159.5, 60.5)];
        for (u, v) in points {
            assert_eq!(a.value(u, v), b.value(u, v));
        }
        assert!(points.iter().any(|&(u, v)| a.value(u, v) != c.value(u, v)));
    }

    #[test]
    fn the_index_finds_every_feature_that_reaches_a_point() {
        let t = texture(11);
        for k in 0..5000 {
            // Inside the extent and up to 20 px beyond it.
            let (u, v) = ((k * 37 % 280) as f64 - 60.3, (k * 53 % 240) as f64 - 60.7);
            let all: f64 = t.features.features.iter().map(|f| f.value(u, v)).sum();
            assert!((t.features.value(u, v) - all).abs() < 1e-9, "({u}, {v})");
        }
    }

    #[test]
    fn grey_levels_stay_in_range_and_vary() {
        let t = texture(5);
        let values: Vec<f64> = (0..10_000)
            .map(|k| t.value((k % 100) as f64 * 1.6, (k / 100) as f64 * 1.2))
            .collect();
        let (min, max) = values
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        assert!(min > -20.0 && max < 280.0, "{min}..{max}");
        assert!(max - min > 100.0);
    }
}

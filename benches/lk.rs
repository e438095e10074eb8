//! Host timings of the per-frame core: pyramids and sparse LK on a seeded synthetic pair.
//!
//! `cargo bench --bench lk`. The comparison with OpenCV on the same frames is
//! `bench/lk_vs_opencv.py`; this benchmark tracks the library's own cost over time.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use host_sim::synth::{grid_points, pair, Homography, SceneSpec};
use host_sim::Frame;
use kestrel::lk::{scratch_len, Illumination, LkParams, LucasKanade, PointTrack};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::ImageView;
use kestrel::Point;

const LEVELS: usize = 3;

fn frames() -> (Frame, Frame) {
    let spec = SceneSpec::new(320, 240, 7).with_noise(1.5);
    pair(&spec, &Homography::translation(6.3, -4.2))
}

fn bench_pyramid(c: &mut Criterion) {
    let (a, _) = frames();
    let view = ImageView::packed(&a.data, a.width, a.height).expect("frame");
    let mut storage = vec![0u8; pyramid_storage_len(a.width, a.height, LEVELS)];
    c.bench_function("pyramid 320x240, 3 levels", |b| {
        b.iter(|| Pyramid::build(view, LEVELS, &mut storage).map(|p| p.max_level()))
    });
}

fn bench_lk(c: &mut Criterion) {
    let (a, b) = frames();
    let points: Vec<Point> = grid_points(a.width, a.height, 15, 10.0)
        .into_iter()
        .take(300)
        .map(|(x, y)| Point::from_f32(x, y))
        .collect();
    let mut group = c.benchmark_group("lk 300 points 320x240, pyramids included");
    group.throughput(Throughput::Elements(points.len() as u64));
    for window in [21, 9] {
        for illumination in [Illumination::GainBias, Illumination::Plain] {
            let params = LkParams {
                window,
                illumination,
                ..LkParams::default()
            };
            let lk = LucasKanade::new(params).expect("params");
            let mut out = vec![PointTrack::default(); points.len()];
            let mut scratch = vec![0i16; scratch_len(window)];
            let mut sa = vec![0u8; pyramid_storage_len(a.width, a.height, LEVELS)];
            let mut sb = sa.clone();
            let name = format!("window {window} {illumination:?}");
            group.bench_function(name, |bench| {
                bench.iter_batched(
                    || (),
                    |()| {
                        let va = ImageView::packed(&a.data, a.width, a.height).expect("a");
                        let vb = ImageView::packed(&b.data, b.width, b.height).expect("b");
                        let prev = Pyramid::build(va, LEVELS, &mut sa).expect("prev");
                        let next = Pyramid::build(vb, LEVELS, &mut sb).expect("next");
                        lk.track_points(&prev, &next, &points, None, &mut out, &mut scratch)
                    },
                    BatchSize::SmallInput,
                )
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench_pyramid, bench_lk);
criterion_main!(benches);

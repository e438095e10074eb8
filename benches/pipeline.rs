//! Host timings of every per-frame stage at the flight-controller size, 160x120: the pyramid,
//! both detectors, a tracker frame, the dense grid with motion boxes, and the robust fit.
//!
//! `cargo bench --bench pipeline`. The same stages on the emulated Cortex-M4 are counted in
//! instructions by `bench/target.sh`; this benchmark follows their cost on the host.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use host_sim::dense::{DenseRunner, MotionRunner, MotionSettings};
use host_sim::synth::{pair, Homography, SceneSpec};
use host_sim::tracking::{config_for, HostBuffers};
use host_sim::Frame;
use kestrel::dense::DenseParams;
use kestrel::detect::{fast_scratch_len, shi_tomasi_scratch_len, Corner, Fast, Region, ShiTomasi};
use kestrel::ego::{ModelKind, Ransac, RansacParams};
use kestrel::pyramid::{pyramid_storage_len, Pyramid};
use kestrel::track::Tracker;
use kestrel::ImageView;

const WIDTH: usize = 160;
const HEIGHT: usize = 120;
const TRACKS: usize = 100;

/// A textured frame and the same scene moved by a sub-pixel shift, with sensor noise.
fn frames() -> (Frame, Frame) {
    let spec = SceneSpec::new(WIDTH, HEIGHT, 11).with_noise(1.0);
    pair(&spec, &Homography::translation(1.35, -0.8))
}

fn view(frame: &Frame) -> ImageView<'_> {
    ImageView::packed(&frame.data, frame.width, frame.height).expect("a valid frame")
}

fn bench_pyramid(c: &mut Criterion) {
    let (a, _) = frames();
    let mut storage = vec![0u8; pyramid_storage_len(WIDTH, HEIGHT, 2)];
    c.bench_function("pyramid 160x120, levels 1-2", |b| {
        b.iter(|| Pyramid::build(view(&a), 2, &mut storage).map(|p| p.max_level()))
    });
}

fn bench_detectors(c: &mut Criterion) {
    let (a, _) = frames();
    let image = view(&a);
    let region = Region::full(&image);
    let mut corners = vec![Corner::default(); 300];
    let mut group = c.benchmark_group("detection 160x120, 300 corners");
    let mut fast_rows = vec![0u8; fast_scratch_len(WIDTH)];
    group.bench_function("FAST-9, threshold 10", |b| {
        b.iter(|| Fast::default().detect(&image, region, None, &mut fast_rows, &mut corners))
    });
    let mut sums = vec![0i32; shi_tomasi_scratch_len(WIDTH, corners.len())];
    group.bench_function("Shi-Tomasi, block 3", |b| {
        b.iter(|| ShiTomasi::default().detect(&image, region, None, &mut sums, &mut corners))
    });
    group.finish();
}

/// The two frames alternate, so every frame follows every track by the same shift forth and
/// back: the steady state of a tracker, with refills where the gates drop tracks.
fn bench_tracker(c: &mut Criterion) {
    let (a, b) = frames();
    let config = config_for(WIDTH, HEIGHT, TRACKS);
    let mut buffers = HostBuffers::new(&config, WIDTH, HEIGHT);
    let mut tracker =
        Tracker::<TRACKS>::new(config, WIDTH, HEIGHT, buffers.lend()).expect("tracker");
    tracker.start(view(&a)).expect("first frame");
    let mut forth = true;
    let mut group = c.benchmark_group("tracker 160x120, window 21, 3 levels");
    group.throughput(Throughput::Elements(TRACKS as u64));
    group.bench_function("one frame, 100 tracks", |bench| {
        bench.iter(|| {
            let (prev, next) = if forth { (&a, &b) } else { (&b, &a) };
            forth = !forth;
            tracker.process(view(prev), view(next), None)
        })
    });
    group.finish();
}

fn bench_dense(c: &mut Criterion) {
    let (a, b) = frames();
    let mut group = c.benchmark_group("dense 160x120, 8 px cells");
    let mut dense = DenseRunner::new(DenseParams::default(), WIDTH, HEIGHT).expect("dense");
    group.bench_function("grid flow, pyramids included", |bench| {
        bench.iter(|| dense.compute(&a, &b))
    });
    let mut motion = MotionRunner::new(MotionSettings::default(), WIDTH, HEIGHT).expect("motion");
    let mut forth = true;
    group.bench_function("grid flow, camera motion and boxes, per frame", |bench| {
        bench.iter(|| {
            forth = !forth;
            motion.push(if forth { a.clone() } else { b.clone() })
        })
    });
    group.finish();
}

fn bench_ransac(c: &mut Criterion) {
    // 100 tracks of a turning camera, one in four thrown off: a typical frame's fit.
    let truth = Homography::similarity(1.01, 0.02, (1.5, -0.7), (80.0, 60.0));
    let tracks: Vec<((f32, f32), (f32, f32))> = (0..TRACKS)
        .map(|i| {
            let (x, y) = ((i % 10) as f64 * 15.0 + 8.0, (i / 10) as f64 * 11.0 + 6.0);
            let (u, v) = truth.apply(x, y);
            let off = if i % 4 == 0 { 6.0 } else { 0.0 };
            ((x as f32, y as f32), ((u + off) as f32, (v - off) as f32))
        })
        .collect();
    let mut inliers = vec![false; tracks.len()];
    let mut group = c.benchmark_group("robust fit, 100 tracks, 25 % outliers");
    for model in [ModelKind::Similarity, ModelKind::Homography] {
        let ransac = Ransac::new(RansacParams {
            model,
            ..RansacParams::default()
        })
        .expect("parameters");
        group.bench_function(format!("{model:?}"), |b| {
            b.iter(|| ransac.estimate(&tracks, &mut inliers))
        });
    }
    group.finish();
}

criterion_group!(
    pipeline,
    bench_pyramid,
    bench_detectors,
    bench_tracker,
    bench_dense,
    bench_ransac
);
criterion_main!(pipeline);

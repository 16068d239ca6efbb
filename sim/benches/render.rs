//! Rendering speed, one thread: `cargo bench -p deckwatch-sim --bench render`. Full frames of
//! the Pi camera, and the 640x480 frames the closed-loop trials render (`deckwatch trials`: the
//! realistic look, the vehicle 3 m over the deck while it waits, 1.5 m during the descent).

use criterion::{criterion_group, criterion_main, Criterion};
use deckwatch_common::{CameraModel, DeckLayout, GrayImage, Rpy, SceneGeometry, Viewpoint};
use deckwatch_sim::{RenderOptions, Renderer};

fn bench(c: &mut Criterion) {
    let cam = CameraModel::rpi_v2();
    let scene = |roll: f64| SceneGeometry {
        attitude: Rpy::from_degrees(roll, 6.0, 3.0).to_matrix(),
        viewpoint: Viewpoint::level(0.2, -0.1, 5.0),
    };
    let mut img = GrayImage::new(3280, 2464);
    let mut group = c.benchmark_group("render_3280x2464");
    group.sample_size(20);
    for (name, opts, sub) in [
        ("clean", RenderOptions::default(), 1),
        ("realistic", RenderOptions::realistic(), 1),
        ("realistic_motion_blur_8", RenderOptions::realistic(), 8),
    ] {
        let mut r = Renderer::new(cam, DeckLayout::paper(), opts, 1).unwrap();
        let exposure: Vec<SceneGeometry> = (0..sub).map(|k| scene(15.0 + 0.1 * k as f64)).collect();
        let mut seed = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                seed += 1;
                r.render(&exposure, seed, &mut img.view_mut()).unwrap();
            })
        });
    }
    let mut distorted = cam;
    distorted.distortion = deckwatch_common::Distortion::from_array([-0.2, 0.05, 0.0, 0.0, 0.0]);
    let mut r = Renderer::new(distorted, DeckLayout::paper(), RenderOptions::realistic(), 1).unwrap();
    group.bench_function("realistic_lens_distortion", |b| {
        b.iter(|| r.render(&[scene(15.0)], 1, &mut img.view_mut()).unwrap())
    });
    group.finish();
}

fn bench_trial(c: &mut Criterion) {
    let cam = CameraModel::rpi_v2().scaled_to(640, 480);
    let mut img = GrayImage::new(640, 480);
    let mut group = c.benchmark_group("render_640x480_trial");
    let mut r = Renderer::new(cam, DeckLayout::paper(), RenderOptions::realistic(), 1).unwrap();
    for (name, height_m) in [("hover_3m", 3.0), ("descent_1_5m", 1.5)] {
        let scene = [SceneGeometry {
            attitude: Rpy::from_degrees(2.0, -1.5, 3.0).to_matrix(),
            viewpoint: Viewpoint::level(0.08, -0.05, height_m),
        }];
        let mut seed = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                seed += 1;
                r.render(&scene, seed, &mut img.view_mut()).unwrap();
            })
        });
    }
    // A renderer per approach: the deck and sea textures.
    group.bench_function("new_renderer", |b| {
        b.iter(|| Renderer::new(cam, DeckLayout::paper(), RenderOptions::realistic(), 1).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench, bench_trial);
criterion_main!(benches);

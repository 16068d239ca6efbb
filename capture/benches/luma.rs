//! The camera path's one copy: luminance of a 3280x2464 camera frame into a packed frame, per
//! pixel format family: `cargo bench -p deckwatch-capture --bench luma`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use deckwatch_capture::camera::LumaLayout;

fn bench(c: &mut Criterion) {
    let (w, h) = (3280usize, 2464usize);
    let mut out = vec![0u8; w * h];
    let mut group = c.benchmark_group("luma_3280x2464");
    group.sample_size(30);
    group.throughput(Throughput::Elements((w * h) as u64));
    for format in ["NV12", "YUYV", "RGB888", "XRGB8888"] {
        let layout = LumaLayout::for_format(format).unwrap();
        // Rows padded to 64 bytes, as camera buffers often are.
        let stride = layout.row_bytes(w).next_multiple_of(64);
        let src: Vec<u8> = (0..stride * h).map(|i| (i * 7 % 251) as u8).collect();
        group.bench_function(format, |b| {
            b.iter(|| layout.extract(&src, stride, w, h, &mut out, w).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

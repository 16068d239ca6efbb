//! The renderer draws into the caller's buffer without allocating per frame (after the first
//! frames have sized its marker patches). Counted with a global allocator, in a test binary of
//! its own so that nothing else allocates meanwhile.

use deckwatch_common::{CameraModel, DeckLayout, GrayImage, SceneGeometry};
use deckwatch_sim::{RenderOptions, Renderer, Scenario};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn rendering_a_frame_does_not_allocate() {
    let cam = CameraModel::rpi_v2().scaled_to(640, 480);
    let mut opts = RenderOptions::realistic();
    opts.optical_blur_px = 1.2;
    let mut cam_d = cam;
    cam_d.distortion = deckwatch_common::Distortion::from_array([-0.2, 0.05, 0.0, 0.0, 0.0]);
    let ship = Scenario::Ship.profile(1, 1.0);
    // Eight sub-exposures (motion blur) per frame.
    let exposure = |k: usize| -> Vec<SceneGeometry> {
        (0..8)
            .map(|j| {
                let s = ship.sample(k as f64 * 0.1 + j as f64 * 0.002);
                SceneGeometry {
                    attitude: s.attitude.to_matrix(),
                    viewpoint: s.viewpoint,
                }
            })
            .collect()
    };
    for camera in [cam, cam_d] {
        let mut r = Renderer::new(camera, DeckLayout::paper(), opts.clone(), 1).unwrap();
        let mut img = GrayImage::new(640, 480);
        // Warm-up: the marker patches grow to the largest marker seen.
        for k in 0..20 {
            r.render(&exposure(k), k as u64, &mut img.view_mut()).unwrap();
        }
        let poses = exposure(20);
        let mut view = img.view_mut();
        let before = ALLOCATIONS.load(Ordering::Relaxed);
        r.render(&poses, 20, &mut view).unwrap();
        let after = ALLOCATIONS.load(Ordering::Relaxed);
        assert_eq!(after - before, 0, "allocations while rendering one frame");
    }
}

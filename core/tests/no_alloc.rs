//! `step()` allocates nothing once the world is warm: proven with a counting
//! global allocator (this test binary's only test, so no other thread
//! allocates while it counts).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};

use lockstep_core::shape::{Cuboid, Shape, Sphere};
use lockstep_core::{BodyDesc, ColliderDesc, Quat, Scalar, Transform, Vec3, World, WorldConfig};

struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn s(v: f64) -> Scalar {
    Scalar::from_f64_lossy(v)
}

#[test]
fn step_does_not_allocate_once_warm() {
    let mut w = World::new(WorldConfig::default()).unwrap();
    for i in 0..50 {
        let f = i as f64;
        let b = w
            .create_body(
                &BodyDesc::dynamic()
                    .position(Vec3::new(s(f), s(10.0), Scalar::ZERO))
                    .angular_velocity(Vec3::new(s(1.0), s(2.0 + f * 0.1), s(0.5))),
            )
            .unwrap();
        let shape = if i % 2 == 0 {
            Shape::Cuboid(Cuboid {
                half_extents: Vec3::new(s(0.2), s(0.5), s(0.9)),
            })
        } else {
            Shape::Sphere(Sphere { radius: s(0.5) })
        };
        w.add_collider(b, ColliderDesc::new(shape)).unwrap();
    }
    let k = w.create_body(&BodyDesc::kinematic()).unwrap();
    for _ in 0..10 {
        w.step();
    }
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    for t in 0..200 {
        let target = Transform::new(
            Vec3::new(Scalar::from_ratio(t, 60), s(1.0), Scalar::ZERO),
            Quat::IDENTITY,
        );
        w.set_kinematic_target(k, target).unwrap();
        let r = w.step();
        assert!(r.faults.is_empty());
    }
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert_eq!(
        after - before,
        0,
        "step() allocated {} times",
        after - before
    );
}

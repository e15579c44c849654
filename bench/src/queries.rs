//! The `queries` suite: scene queries and a mesh build, ours alone (the
//! figures that used to be printed by ignored core tests).
//!
//! - the closest hit of a ray across a world of 1,000 fixed boxes (a
//!   10 × 10 × 10 grid, 3 m apart), on rays drawn across the grid;
//! - a sphere (radius 0.25 m) swept along the first of those rays;
//! - `TriMesh::new` (its tree and edge flags) of loose random triangles.
//!
//! Each figure is the best of the runs, like the `math` suite's.

use std::fmt::Write as _;
use std::hint::black_box;
use std::time::Instant;

use lockstep_core::query::{QueryFilter, Ray};
use lockstep_core::shape::{Cuboid, Shape, Sphere, TriMesh};
use lockstep_core::{BodyDesc, ColliderDesc, Transform, Vec3, World, WorldConfig};
use lockstep_testsupport::{Rng, s, v};

use crate::{Options, SuiteOutput};

/// One measured case.
struct Row {
    case: &'static str,
    /// Calls per run.
    count: usize,
    /// Best nanoseconds per call.
    ns: f64,
    /// Calls that hit something (queries), or 0.
    hits: usize,
}

/// The grid of 1,000 fixed unit boxes, without gravity.
fn boxes() -> World {
    let mut w = World::new(WorldConfig {
        gravity: Vec3::ZERO,
        ..WorldConfig::default()
    })
    .expect("world");
    let cube = Shape::Cuboid(Cuboid::new(v(0.5, 0.5, 0.5)).expect("box"));
    for i in 0..1000 {
        let at = v(
            (i % 10) as f64 * 3.0,
            ((i / 10) % 10) as f64 * 3.0,
            (i / 100) as f64 * 3.0,
        );
        let b = w
            .create_body(&BodyDesc::fixed().position(at))
            .expect("body");
        w.add_collider(b, ColliderDesc::new(cube.clone()))
            .expect("collider");
    }
    w
}

/// Rays from x = −5 to x = 35 at random heights and depths over the grid.
fn rays(n: usize) -> Vec<Ray> {
    let mut rng = Rng::new(5);
    (0..n)
        .map(|_| {
            let o = v(-5.0, rng.uniform(0.0, 30.0), rng.uniform(0.0, 30.0));
            let e = v(35.0, rng.uniform(0.0, 30.0), rng.uniform(0.0, 30.0));
            Ray::new(o, e - o)
        })
        .collect()
}

/// The best time of `runs` runs of `f`, in nanoseconds per call of `count`
/// calls, and what the last run returned.
fn best<R>(runs: usize, count: usize, mut f: impl FnMut() -> R) -> (f64, R) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        let r = black_box(f());
        best = best.min(t.elapsed().as_nanos() as f64 / count.max(1) as f64);
        last = Some(r);
    }
    (best, last.expect("one run"))
}

/// Runs the suite.
pub fn run(opts: &Options) -> SuiteOutput {
    let runs = opts.runs.unwrap_or(if opts.quick { 1 } else { 5 });
    let (n_rays, n_sweeps, n_triangles) = if opts.quick {
        (500, 50, 2_000)
    } else {
        (20_000, 2_000, 100_000)
    };
    let w = boxes();
    let rays = rays(n_rays);
    let filter = QueryFilter::default();
    let mut rows = Vec::new();

    let (ns, hits) = best(runs, rays.len(), || {
        rays.iter()
            .filter(|r| w.cast_ray_closest(r, &filter).is_some())
            .count()
    });
    rows.push(Row {
        case: "closest ray vs 1000 boxes",
        count: rays.len(),
        ns,
        hits,
    });

    let ball = Shape::Sphere(Sphere::new(s(0.25)).expect("sphere"));
    let (ns, hits) = best(runs, n_sweeps, || {
        rays.iter()
            .take(n_sweeps)
            .filter(|r| {
                let pose = Transform::from_translation(r.origin);
                w.cast_shape(&ball, &pose, r.translation, &filter)
                    .expect("sweep")
                    .is_some()
            })
            .count()
    });
    rows.push(Row {
        case: "sphere sweep vs 1000 boxes",
        count: n_sweeps,
        ns,
        hits,
    });

    let mut rng = Rng::new(4);
    let verts: Vec<Vec3> = (0..3 * n_triangles)
        .map(|_| {
            v(
                rng.uniform(-500.0, 500.0),
                rng.uniform(-5.0, 5.0),
                rng.uniform(-500.0, 500.0),
            )
        })
        .collect();
    let idx: Vec<[u32; 3]> = (0..n_triangles as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
    let (ns, _) = best(runs, 1, || {
        TriMesh::new(verts.clone(), idx.clone()).expect("mesh")
    });
    rows.push(Row {
        case: "TriMesh::new of loose triangles",
        count: n_triangles,
        ns,
        hits: 0,
    });

    let mut text = format!("best of {runs} runs\n");
    let _ = writeln!(
        text,
        "{:<34} {:>8} {:>14} {:>8}",
        "case", "count", "per call", "hits"
    );
    let mut csv = String::from("suite,case,count,ns_per_call,hits\n");
    for r in &rows {
        let per_call = if r.ns >= 1e6 {
            format!("{:.1} ms", r.ns / 1e6)
        } else {
            format!("{:.0} ns", r.ns)
        };
        let _ = writeln!(
            text,
            "{:<34} {:>8} {:>14} {:>8}",
            r.case, r.count, per_call, r.hits
        );
        let _ = writeln!(csv, "queries,{},{},{:.1},{}", r.case, r.count, r.ns, r.hits);
    }
    SuiteOutput { text, csv }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quick_run_reports_every_case_and_most_rays_hit() {
        let out = run(&Options {
            quick: true,
            ..Options::default()
        });
        assert_eq!(out.csv.lines().count(), 4);
        let rays: Vec<&str> = out.csv.lines().nth(1).unwrap().split(',').collect();
        let hits: usize = rays[4].parse().unwrap();
        assert!(hits > 250, "{hits} of 500 rays hit");
    }
}

//! Whether a convex shape at a pose intersects another shape: the exact
//! test behind the world's overlap query, and the mesh and height-field
//! triangle walks that sweeps share.

use super::convex::{QueryError, Triangle, convex_support};
use super::ray::{cell_span, triangle_outside};
use crate::collision::narrow::gjk::{DistanceResult, distance};
use crate::math::{Aabb, Transform, Vec3};
use crate::shape::Shape;

/// A box as raw bits per axis (`[lo, hi]`), for exact pruning.
pub(crate) type RawBox = ([i128; 3], [i128; 3]);

/// The raw bits of a box.
pub(crate) fn raw_box(b: &Aabb) -> RawBox {
    (
        b.min.to_array().map(|c| c.to_bits() as i128),
        b.max.to_array().map(|c| c.to_bits() as i128),
    )
}

/// Calls `f(index, triangle)` (local corners) for each triangle of a mesh
/// or height field whose box touches `local` (the shape's local frame), in a
/// fixed order, until `f` returns `false`: mesh triangles by index; height
/// field cells row by row, column by column, the two triangles of a cell in
/// [`HeightField::cell_triangles`](crate::shape::heightfield::HeightField::cell_triangles)
/// order, numbered `2 · (row · (cols − 1) + col) + k`. Convex shapes have no
/// triangles: nothing is called.
///
/// Meshes are walked linearly for now; the walk becomes a BVH descent once
/// meshes carry one (the order of the reported triangles stays the index
/// order).
pub(crate) fn for_each_triangle(
    shape: &Shape,
    local: &RawBox,
    mut f: impl FnMut(usize, [Vec3; 3]) -> bool,
) {
    let (lo, hi) = local;
    match shape {
        Shape::TriMesh(m) => {
            for i in 0..m.indices().len() {
                if let Some(tri) = m.triangle(i)
                    && !triangle_outside(&tri, lo, hi)
                    && !f(i, tri)
                {
                    return;
                }
            }
        }
        Shape::HeightField(hf) => {
            let (Some(corner), scale) = (hf.vertex(0, 0), hf.scale()) else {
                return;
            };
            let Some((r0, r1)) = cell_span(lo[2], hi[2], corner.z, scale.z, hf.rows() - 1) else {
                return;
            };
            let Some((c0, c1)) = cell_span(lo[0], hi[0], corner.x, scale.x, hf.cols() - 1) else {
                return;
            };
            let cells = hf.cols() as usize - 1;
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let Some(tris) = hf.cell_triangles(r, c) else {
                        continue;
                    };
                    for (k, tri) in tris.into_iter().enumerate() {
                        let idx = 2 * (r as usize * cells + c as usize) + k;
                        if !triangle_outside(&tri, lo, hi) && !f(idx, tri) {
                            return;
                        }
                    }
                }
            }
        }
        _ => {}
    }
}

/// The box of `query` posed at `pose`, seen in the frame of `target_pose`.
pub(crate) fn box_in_frame(query: &Shape, pose: &Transform, target_pose: &Transform) -> Aabb {
    query.aabb(&target_pose.inverse().mul_transform(pose))
}

/// Whether the convex shape `query` at `pose` intersects `target` at
/// `target_pose` (touching within 16 ulps counts, as for
/// the narrow phase's GJK distance). Exact GJK for a
/// convex target; for a mesh or height field, GJK against each triangle
/// whose box touches the query's box.
///
/// # Errors
/// [`QueryError::NonConvexQueryShape`] if `query` is a mesh or height field.
pub fn shapes_overlap(
    query: &Shape,
    pose: &Transform,
    target: &Shape,
    target_pose: &Transform,
) -> Result<bool, QueryError> {
    let a = convex_support(query).ok_or(QueryError::NonConvexQueryShape { kind: query.kind() })?;
    if let Some(b) = convex_support(target) {
        return Ok(matches!(
            distance(a, pose, b, target_pose),
            DistanceResult::Overlapping
        ));
    }
    let local = raw_box(&box_in_frame(query, pose, target_pose));
    let mut hit = false;
    for_each_triangle(target, &local, |_, tri| {
        hit = matches!(
            distance(a, pose, &Triangle(tri), target_pose),
            DistanceResult::Overlapping
        );
        !hit
    });
    Ok(hit)
}

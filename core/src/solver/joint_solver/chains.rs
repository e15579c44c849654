//! Chains: runs of joints whose anchor blocks are solved together, exactly.
//!
//! Gauss–Seidel visits one joint at a time, so a load passes down a chain
//! one link per pass: a weight on light links (1:100) stretches them far
//! before the impulses catch up, and a stiffer spring only makes the
//! overshoot worse. A chain's anchor blocks instead form one linear system
//! `K·x = w` whose matrix is block tridiagonal (3×3 blocks): joint `k`
//! shares a body only with joints `k − 1` and `k + 1`. It is solved exactly
//! in linear time (block Thomas elimination), so every pass leaves every
//! anchor of the chain where the push-out asks, whatever the mass ratio.
//!
//! A chain is a maximal run of joints with an anchor block and no limit or
//! motor (spherical, revolute, fixed) in which each joint shares one moving
//! body with the next and that body carries no other joint; no other joint
//! touches the run's two end bodies, and at least one of them moves (see
//! [`Chains::build`] for why each rule). A ring of joints has no end. The
//! joints left out keep the soft spring, one joint at a time. The other
//! rows of a chained joint (the hinge's two, the weld's lock) are solved
//! one joint at a time as before, then each chain's anchor blocks
//! together, held rigidly.
//!
//! Off the diagonal, joints `k` and `k + 1` share body `B` at arms `r_k`,
//! `r_{k+1}` (world axes from its centre of mass):
//! `K_{k,k+1} = σ_k σ_{k+1} (m⁻¹·1 − [r_k]× I⁻¹ [r_{k+1}]×)`, with `σ = +1`
//! where `B` is the joint's B end and `−1` where it is its A end (an
//! impulse `p` acts `+p` on B and `−p` on A). The diagonal blocks are the
//! joints' own anchor blocks.
//!
//! At each measurement: `S_0 = K_00`, `S_k = K_kk − E_{k−1}ᵀ S_{k−1}⁻¹
//! E_{k−1}` (`E_k = K_{k,k+1}`), and `G_k = S_k⁻¹ E_k`. Per pass: forward
//! `z_k = S_k⁻¹ (w_k − E_{k−1}ᵀ z_{k−1})`, back `x_k = z_k − G_k x_{k+1}`.
//! Each `S_k` is symmetric positive definite (a Schur complement of `K`);
//! one that will not invert (a degenerate chain) sends the chain back to
//! one joint at a time until the next measurement.
//!
//! Determinism: chains in the order of their first joint, joints along
//! the chain; fixed-point arithmetic, every product rounded once.

use crate::math::{Mat3, Scalar, SymMat3, Vec3};
use crate::scratch::Capacities;

use super::rows::{Geometry, Posed, Row, apply_point, point_mass, read, write};
use crate::arena::Arena;
use crate::body::BodyHot;
use crate::joint::Joint;

/// No row.
const NONE: u32 = u32::MAX;

/// Where one chained joint meets the next: whether the body they share is
/// this joint's B end, and whether it is the next joint's.
#[derive(Clone, Copy, Debug, Default)]
struct Link {
    this_b: bool,
    next_b: bool,
}

/// One chained joint's part of the factorisation, at the last
/// measurement.
#[derive(Clone, Copy, Debug, Default)]
struct Factor {
    /// `S_k⁻¹`.
    s_inv: SymMat3,
    /// `E_k = K_{k,k+1}` (zero for the last joint).
    e: Mat3,
    /// `G_k = S_k⁻¹ E_k`.
    g: Mat3,
}

/// The chains of this tick's joints (scratch: rebuilt every tick).
#[derive(Clone, Debug, Default)]
pub(super) struct Chains {
    /// Per body slot: how many listed joints move it, and the first two.
    degree: Vec<u8>,
    first: Vec<[u32; 2]>,
    /// Row indices, chain after chain, each along its chain.
    order: Vec<u32>,
    /// Per chain: its first entry in `order`, its length, and whether its
    /// last factorisation succeeded.
    runs: Vec<(u32, u32, bool)>,
    /// Per entry of `order`: how it meets the next entry.
    links: Vec<Link>,
    /// Per entry of `order`: its factor.
    factors: Vec<Factor>,
    /// Per entry of `order`: `z`, then `x`, during a pass.
    z: Vec<Vec3>,
}

impl Chains {
    /// Finds the chains among `rows` and marks their rows `chained`.
    pub(super) fn build(&mut self, rows: &mut [Row]) {
        self.order.clear();
        self.runs.clear();
        self.links.clear();
        let slots = rows
            .iter()
            .flat_map(|r| [r.a.slot, r.b.slot])
            .max()
            .map_or(0, |s| s as usize + 1);
        if self.degree.len() < slots {
            self.degree.resize(slots, 0);
            self.first.resize(slots, [NONE; 2]);
        }
        for r in rows.iter() {
            self.degree[r.a.slot as usize] = 0;
            self.degree[r.b.slot as usize] = 0;
        }
        for (i, r) in rows.iter_mut().enumerate() {
            r.chained = false;
            for (slot, dynamic) in [(r.a.slot, r.a.dynamic), (r.b.slot, r.b.dynamic)] {
                if !dynamic {
                    continue;
                }
                let d = &mut self.degree[slot as usize];
                if (*d as usize) < 2 {
                    self.first[slot as usize][*d as usize] = i as u32;
                }
                *d = d.saturating_add(1);
            }
        }
        for start in 0..rows.len() {
            if rows[start].chained || !rows[start].chainable {
                continue;
            }
            let ends = [
                across(&self.degree, &self.first, rows, start, false),
                across(&self.degree, &self.first, rows, start, true),
            ];
            // Start only at an end of a run (a ring has none); a joint
            // with no chainable neighbour is a chain of one.
            let out_b = match ends {
                [NONE, _] => true,
                [_, NONE] => false,
                _ => continue,
            };
            let begin = self.order.len();
            // The run's first end (through which it does not go on).
            let first_end = if out_b { rows[start].a } else { rows[start].b };
            let (mut cur, mut out_b) = (start, out_b);
            let last_end = loop {
                rows[cur].chained = true;
                self.order.push(cur as u32);
                let next = across(&self.degree, &self.first, rows, cur, out_b);
                if next == NONE || rows[next as usize].chained {
                    self.links.push(Link::default());
                    break if out_b { rows[cur].b } else { rows[cur].a };
                }
                let shared = if out_b {
                    rows[cur].b.slot
                } else {
                    rows[cur].a.slot
                };
                let n = &rows[next as usize];
                // The shared body is the next joint's B end or its A end
                // (a joint never joins a body to itself).
                let next_b = n.b.slot == shared;
                self.links.push(Link {
                    this_b: out_b,
                    next_b,
                });
                cur = next as usize;
                out_b = !next_b;
            };
            // A run is a chain only where no other joint touches its two
            // ends (a static or kinematic body, or one that only this run
            // moves): there the exact solve holds its anchors rigidly. A
            // run whose end body has other joints meets them one joint at
            // a time, and a rigid anchor there is as unstable as any
            // stiff joint solved so (a grid of such joints blew up); its
            // joints keep the soft spring.
            //
            // A run held at both ends (a bridge between two static bodies)
            // is left out too: pulled straight, its rows along the line
            // are one more than the bodies they move (the last is implied
            // by the others), `K` is singular, and the elimination
            // overflowed; one joint at a time copes with redundant rows.
            // With one end free, every joint brings a body of its own and
            // the rows are independent.
            let free = |e: &super::rows::End| !e.dynamic || self.degree[e.slot as usize] == 1;
            let held_both = !first_end.dynamic && !last_end.dynamic;
            if !free(&first_end) || !free(&last_end) || held_both {
                for &i in &self.order[begin..] {
                    rows[i as usize].chained = false;
                }
                self.order.truncate(begin);
                self.links.truncate(begin);
                continue;
            }
            let len = self.order.len() - begin;
            self.runs.push((begin as u32, len as u32, false));
        }
        self.factors.resize(self.order.len(), Factor::default());
        self.z.resize(self.order.len(), Vec3::ZERO);
    }

    /// The buffers [`build`](Self::build) fills.
    pub(super) fn capacities(&self) -> Capacities<7> {
        Capacities::of([
            &self.degree,
            &self.first,
            &self.order,
            &self.runs,
            &self.links,
            &self.factors,
            &self.z,
        ])
    }

    /// Factorises every chain at the joints' current measurement.
    /// A chain whose factorisation fails gets its joints' own anchor
    /// blocks inverted instead, to be solved one at a time.
    pub(super) fn factor(&mut self, rows: &[Row], posed: &mut [Posed]) {
        for run in &mut self.runs {
            let (begin, len) = (run.0 as usize, run.1 as usize);
            run.2 = true;
            let mut prev: Option<Factor> = None;
            for k in begin..begin + len {
                let i = self.order[k] as usize;
                let (row, g) = (&rows[i], &posed[i].g);
                let mut s = point_mass(row, g.ra, g.rb);
                if let Some(p) = prev {
                    // S_k = K_kk − E_{k−1}ᵀ G_{k−1}.
                    s = s - SymMat3::from_mat3_symmetric_part(&(p.e.transpose() * p.g));
                }
                let Some(s_inv) = s.try_inverse_fast() else {
                    run.2 = false;
                    for &i in &self.order[begin..begin + len] {
                        let (row, p) = (&rows[i as usize], &mut posed[i as usize]);
                        p.point_inv = point_mass(row, p.g.ra, p.g.rb).try_inverse_fast();
                    }
                    break;
                };
                let e = if k + 1 < begin + len {
                    let link = self.links[k];
                    let j = self.order[k + 1] as usize;
                    coupling(row, g, link.this_b, &posed[j].g, link.next_b)
                } else {
                    Mat3::ZERO
                };
                let f = Factor {
                    s_inv,
                    e,
                    g: s_inv.to_mat3() * e,
                };
                self.factors[k] = f;
                prev = Some(f);
            }
        }
    }

    /// The rows of the chains whose last factorisation failed, for the
    /// caller to solve one joint at a time (their own anchor blocks were
    /// inverted by [`factor`](Self::factor)).
    pub(super) fn unsolved(&self) -> impl Iterator<Item = usize> + '_ {
        self.runs
            .iter()
            .filter(|r| !r.2)
            .flat_map(|r| &self.order[r.0 as usize..(r.0 + r.1) as usize])
            .map(|&i| i as usize)
    }

    /// Solves each chain's anchor blocks together (see the module docs),
    /// rigidly, pushing the anchors' error out at `push_out` (zero in a
    /// relax pass). A chain whose last factorisation failed is left out:
    /// its rows are [`unsolved`](Self::unsolved).
    pub(super) fn solve(
        &mut self,
        rows: &[Row],
        posed: &[Posed],
        joints: &mut Arena<Joint>,
        hot: &mut [BodyHot],
        push_out: Scalar,
    ) {
        for &(begin, len, ok) in &self.runs {
            let (begin, len) = (begin as usize, len as usize);
            if !ok {
                continue;
            }
            // Forward: z_k = S_k⁻¹ (w_k − E_{k−1}ᵀ z_{k−1}), with w_k the
            // anchor's rate plus the spring's push-out.
            for k in begin..begin + len {
                let i = self.order[k] as usize;
                let (row, g) = (&rows[i], &posed[i].g);
                let v = read(row, hot);
                let cdot = v.vb + v.wb.cross(g.rb) - v.va - v.wa.cross(g.ra);
                let mut w = if push_out.is_zero() {
                    cdot
                } else {
                    cdot + g.d * push_out
                };
                if k > begin {
                    w -= self.factors[k - 1].e.transpose_mul_vec(self.z[k - 1]);
                }
                self.z[k] = self.factors[k].s_inv.mul_vec(w);
            }
            // Back: x_k = z_k − G_k x_{k+1}.
            for k in (begin..begin + len - 1).rev() {
                let next = self.z[k + 1];
                self.z[k] -= self.factors[k].g.mul_vec(next);
            }
            // Each joint's impulse: −x, the whole effective mass's.
            for k in begin..begin + len {
                let i = self.order[k] as usize;
                let Some(j) = joints.get_by_index_mut(rows[i].joint) else {
                    continue;
                };
                let p = -self.z[k];
                j.impulses.linear += p;
                let row = &rows[i];
                let mut v = read(row, hot);
                apply_point(row, &posed[i].g, &mut v, p);
                write(row, hot, &v);
            }
        }
    }
}

/// The joint across end B (`b`) or A of row `i`, if the moving body there
/// joins exactly two joints with anchor blocks; else [`NONE`].
fn across(degree: &[u8], first: &[[u32; 2]], rows: &[Row], i: usize, b: bool) -> u32 {
    let end = if b { &rows[i].b } else { &rows[i].a };
    if !end.dynamic || degree[end.slot as usize] != 2 || !rows[i].chainable {
        return NONE;
    }
    let [x, y] = first[end.slot as usize];
    let other = if x as usize == i { y } else { x };
    if other == NONE || !rows[other as usize].chainable {
        NONE
    } else {
        other
    }
}

/// `K_{k,k+1}`: how an impulse on the next joint's anchors changes this
/// joint's anchor rate through the body they share (this joint's B end if
/// `this_b`, the next one's if `next_b`).
fn coupling(this: &Row, g: &Geometry, this_b: bool, gn: &Geometry, next_b: bool) -> Mat3 {
    let (end, r1) = if this_b {
        (&this.b, g.rb)
    } else {
        (&this.a, g.ra)
    };
    let r2 = if next_b { gn.rb } else { gn.ra };
    let m = end.inv_mass;
    // m⁻¹·1 − [r1]× I⁻¹ [r2]×; for an isotropic body (I⁻¹ = s·1),
    // [r1]×[r2]× = r2 r1ᵀ − (r1·r2)·1, so the product is s·((r1·r2)·1 −
    // r2 r1ᵀ): twelve products instead of fifty-four.
    let k = if end.isotropic {
        let s = end.inv_inertia.xx;
        let d = m + s * r1.dot(r2);
        let col = |c: Scalar, e: Vec3| -(r2 * (s * c)) + e * d;
        Mat3::from_cols(col(r1.x, Vec3::X), col(r1.y, Vec3::Y), col(r1.z, Vec3::Z))
    } else {
        Mat3::from_diagonal(Vec3::new(m, m, m))
            - Mat3::skew(r1) * (end.inv_inertia.to_mat3() * Mat3::skew(r2))
    };
    if this_b == next_b { k } else { Mat3::ZERO - k }
}

#[cfg(test)]
mod tests {
    use super::super::rows::End;
    use super::*;

    /// A joint between bodies `a` and `b` (slot 0 is static).
    fn row(a: u32, b: u32, chainable: bool) -> Row {
        let end = |slot: u32| End {
            slot,
            dynamic: slot != 0,
            ..End::default()
        };
        Row {
            a: end(a),
            b: end(b),
            chainable,
            ..Row::default()
        }
    }

    fn chains_of(rows: &mut [Row]) -> Vec<Vec<u32>> {
        let mut c = Chains::default();
        c.build(rows);
        c.runs
            .iter()
            .map(|&(begin, len, _)| c.order[begin as usize..(begin + len) as usize].to_vec())
            .collect()
    }

    #[test]
    fn a_run_from_a_static_body_to_a_free_end_is_one_chain_in_order() {
        // Listed out of order: 2–3, static–1, 1–2; the chain runs from
        // either end, starting at the first row that ends it.
        let mut rows = [row(2, 3, true), row(0, 1, true), row(2, 1, true)];
        assert_eq!(chains_of(&mut rows), vec![vec![0, 2, 1]]);
        assert!(rows.iter().all(|r| r.chained));
        // A single pendulum is a chain of one.
        let mut one = [row(0, 1, true)];
        assert_eq!(chains_of(&mut one), vec![vec![0]]);
    }

    #[test]
    fn runs_touching_other_joints_rings_and_limited_joints_stay_single() {
        // Body 2 carries a third joint: neither run through it is a chain,
        // nor the third joint.
        let mut branched = [
            row(0, 1, true),
            row(1, 2, true),
            row(2, 3, true),
            row(2, 4, true),
        ];
        assert!(chains_of(&mut branched).is_empty());
        assert!(branched.iter().all(|r| !r.chained));
        // A ring has no end.
        let mut ring = [row(1, 2, true), row(2, 3, true), row(3, 1, true)];
        assert!(chains_of(&mut ring).is_empty());
        // A limited joint in the middle: the runs beside it end at a body
        // it also moves.
        let mut limited = [row(0, 1, true), row(1, 2, false), row(2, 3, true)];
        assert!(chains_of(&mut limited).is_empty());
        // A bridge: held at both ends.
        let mut bridge = [row(0, 1, true), row(1, 2, true), row(2, 0, true)];
        assert!(chains_of(&mut bridge).is_empty());
        // Two joints between the same two bodies close a ring of two.
        let mut double = [row(1, 2, true), row(1, 2, true)];
        assert!(chains_of(&mut double).is_empty());
        // Two separate chains, in the order of their first rows.
        let mut two = [
            row(0, 5, true),
            row(0, 1, true),
            row(1, 2, true),
            row(6, 5, true),
        ];
        assert_eq!(chains_of(&mut two), vec![vec![0, 3], vec![1, 2]]);
    }
}

//! A drive's range as linear constraints, block by block, and the bounded
//! least-squares step of the inverse kinematics.
//!
//! The drive's coordinates come in equal blocks that share the same rows
//! `a_r . x_s <= b_r`:
//! * muscles: a section's curvature `k` is within range when no two of its
//!   muscles differ in length by more than the range's span (the common mode
//!   centres the three in the range): `(lever_i - lever_j) . k <= span` for
//!   the six ordered pairs, a hexagon in the `(kappa_x, kappa_y)` plane;
//! * tendons: each tension alone, `-t <= 0` and `t <= max_tension`.
//!
//! The step
//!
//! ```text
//! minimise |d - r|^2 + |J d - e|^2 / c   subject to   x + d within range
//! ```
//!
//! is the minimum-norm Gauss-Newton step (`r = x_ref - x`) as `c -> 0` and a
//! Levenberg-Marquardt step for `r = 0` and `c = mu`. It is solved by a
//! primal active-set method from `d = 0` (feasible), with `H^{-1}` applied by
//! the Woodbury identity, so a step costs O(m) a working-set row and a step
//! that stays within range costs one pass over the constraints.

use super::Muscles;
use nalgebra::{DMatrix, DVector};
use std::ops::ControlFlow;

/// Rounds of the active-set method before it settles for its current
/// (feasible, improved) point.
const MAX_ROUNDS: usize = 60;

/// Equal blocks of coordinates that share the rows `a_r . x_s <= b_r`.
#[derive(Debug, Clone)]
struct Group {
    /// Coordinates a block.
    block: usize,
    /// Blocks in the group; `None`: every coordinate up to the later groups'.
    count: Option<usize>,
    /// `a_r`, `block` coefficients a row, row after row.
    rows: Vec<f64>,
    /// `b_r`, one a row.
    limits: Vec<f64>,
}

/// The drive's range: groups of blocks, one after another along `x`.
#[derive(Debug, Clone)]
pub(crate) struct Bounds {
    groups: Vec<Group>,
}

/// A bounded step and how many constraints hold it back.
pub(crate) struct BoundedStep {
    pub step: DVector<f64>,
    /// Working-set rows at the end (constraints that limit the step).
    pub blocking: usize,
}

impl Bounds {
    fn one(block: usize, rows: Vec<f64>, limits: Vec<f64>) -> Self {
        Bounds {
            groups: vec![Group {
                block,
                count: None,
                rows,
                limits,
            }],
        }
    }

    /// The muscles' length range in sections `section_length` long (see
    /// the module docs).
    pub fn muscles(muscles: &Muscles, section_length: f64) -> Self {
        let lever = muscles.lever(section_length);
        let pairs = [(0, 1), (1, 2), (2, 0), (1, 0), (2, 1), (0, 2)];
        let span = muscles.length_range[1] - muscles.length_range[0];
        Bounds::one(
            2,
            pairs
                .iter()
                .flat_map(|&(i, j)| [lever[i][0] - lever[j][0], lever[i][1] - lever[j][1]])
                .collect(),
            vec![span; 6],
        )
    }

    /// Tensions between zero and `upper` (none: no upper bound).
    pub fn tensions(upper: Option<f64>) -> Self {
        match upper {
            Some(upper) => Bounds::one(1, vec![-1.0, 1.0], vec![0.0, upper]),
            None => Bounds::one(1, vec![-1.0], vec![0.0]),
        }
    }

    /// No limit on any coordinate.
    pub fn none() -> Self {
        Bounds::one(1, Vec::new(), Vec::new())
    }

    /// These bounds on the leading coordinates and one more coordinate,
    /// the last, within `[lo, hi]` (an insertion).
    pub fn and_interval(mut self, [lo, hi]: [f64; 2]) -> Self {
        self.groups.push(Group {
            block: 1,
            count: Some(1),
            rows: vec![-1.0, 1.0],
            limits: vec![-lo, hi],
        });
        self
    }

    /// Group `g`'s block count for `len` coordinates.
    fn count(&self, g: usize, len: usize) -> usize {
        let group = &self.groups[g];
        group.count.unwrap_or_else(|| {
            let fixed: usize = self
                .groups
                .iter()
                .filter_map(|g| g.count.map(|c| c * g.block))
                .sum();
            (len - fixed.min(len)) / group.block
        })
    }

    /// `f` of every row for `len` coordinates, group after group, block
    /// after block, until it breaks (no allocation: a step walks them often).
    fn each_limit<'a>(&'a self, len: usize, mut f: impl FnMut(Limit<'a>) -> ControlFlow<()>) {
        let mut first = 0;
        for (g, group) in self.groups.iter().enumerate() {
            let count = self.count(g, len);
            for s in 0..count {
                for (r, &b) in group.limits.iter().enumerate() {
                    let limit = Limit {
                        at: first + s * group.block,
                        a: &group.rows[r * group.block..(r + 1) * group.block],
                        b,
                    };
                    if f(limit).is_break() {
                        return;
                    }
                }
            }
            first += count * group.block;
        }
    }

    /// The widest row's norm.
    fn widest(&self) -> f64 {
        self.groups
            .iter()
            .flat_map(|g| g.rows.chunks(g.block.max(1)))
            .map(|a| a.iter().map(|x| x * x).sum::<f64>().sqrt())
            .fold(0.0, f64::max)
    }

    /// The step defined in the module docs, from `x` (within range).
    /// `None` if `c I + J J^T` is singular.
    pub fn step(
        &self,
        x: &DVector<f64>,
        j: &DMatrix<f64>,
        e: &DVector<f64>,
        r: &DVector<f64>,
        c: f64,
    ) -> Option<BoundedStep> {
        let rows = j.nrows();
        let g = (j * j.transpose() + DMatrix::identity(rows, rows) * c).cholesky()?;
        // The unconstrained minimiser, in the form that stays exact as c -> 0.
        let free = r + j.tr_mul(&g.solve(&(e - j * r)));
        // The free step, where it stays within range, is the answer: one
        // pass over the rows (the muscles' 60, mostly), no table.
        let (len, tiny_scale) = (x.len(), self.widest());
        let tiny = 1e-12 * free.norm() * tiny_scale;
        let mut within = true;
        self.each_limit(len, |limit| {
            let rate = limit.dot(&free);
            if rate > tiny && limit.room(x) / rate < 1.0 {
                within = false;
                return ControlFlow::Break(());
            }
            ControlFlow::Continue(())
        });
        if within {
            return Some(BoundedStep {
                step: free,
                blocking: 0,
            });
        }
        let count = (0..self.groups.len())
            .map(|g| self.count(g, len) * self.groups[g].limits.len())
            .sum();
        let mut limits = Vec::with_capacity(count);
        self.each_limit(len, |limit| {
            limits.push(limit);
            ControlFlow::Continue(())
        });
        let mut qp = ActiveSet {
            start: x,
            h_rows: Vec::new(),
            limits,
            tiny_scale,
            free,
            g: &g,
            j,
            h_inv: None,
            work: Vec::new(),
            x: DVector::zeros(len),
        };
        Some(qp.solve())
    }
}

/// A row of the range as one step sees it, `a . x[at..] <= b` (formed once
/// a step: the active-set rounds walk the rows often).
#[derive(Clone, Copy)]
struct Limit<'a> {
    at: usize,
    a: &'a [f64],
    b: f64,
}

impl Limit<'_> {
    fn dot(&self, v: &DVector<f64>) -> f64 {
        self.a
            .iter()
            .zip(&v.as_slice()[self.at..])
            .map(|(a, x)| a * x)
            .sum()
    }

    /// The room it leaves at `x` (never negative: `x` is within range).
    fn room(&self, x: &DVector<f64>) -> f64 {
        (self.b - self.dot(x)).max(0.0)
    }
}

/// The primal active-set method on one step (see the module docs).
struct ActiveSet<'a> {
    /// Where the step starts (within range).
    start: &'a DVector<f64>,
    limits: Vec<Limit<'a>>,
    /// The widest row's norm: the scale of a rate at rounding level.
    tiny_scale: f64,
    free: DVector<f64>,
    /// `c I + J J^T` factored, and `J`: `H^{-1} = I - J^T (c I + J J^T)^{-1} J`
    /// (Woodbury), formed once where a row is first held (a row's
    /// `H^{-1} a_r` is then its coefficients' columns).
    g: &'a nalgebra::Cholesky<f64, nalgebra::Dyn>,
    j: &'a DMatrix<f64>,
    h_inv: Option<DMatrix<f64>>,
    /// `H^{-1} a_r` of the rows the working set has held, each computed once.
    h_rows: Vec<(usize, DVector<f64>)>,
    /// Working set: the rows (indices of `limits`) held with equality.
    work: Vec<usize>,
    /// Current (feasible) point.
    x: DVector<f64>,
}

impl ActiveSet<'_> {
    fn solve(&mut self) -> BoundedStep {
        // The free step crosses a row (see `Bounds::step`): the search starts
        // at `d = 0` holding the rows `x` is on that the free step would
        // cross: the bounds the last step ended on, usually the ones this
        // step ends on (a tendon slack at zero), each otherwise dropped in
        // one round.
        self.work = self.rows_held_at_start();
        for _ in 0..MAX_ROUNDS {
            let Some((target, nu)) = self.equality_minimiser() else {
                break;
            };
            let d = self.hold(&target - &self.x);
            if d.norm() <= 1e-12 * (1.0 + self.x.norm()) {
                // The multiplier of row i is -nu_i; drop the most negative.
                let worst = nu
                    .iter()
                    .enumerate()
                    .max_by(|a, b| a.1.total_cmp(b.1))
                    .filter(|(_, v)| **v > 1e-12 * nu.amax());
                match worst {
                    Some((i, _)) => {
                        self.work.remove(i);
                        continue;
                    }
                    None => break,
                }
            }
            let (alpha, blocking) = self.ratio_test(&self.x, &d, true);
            self.x += d * alpha;
            if let Some(row) = blocking {
                self.work.push(row);
            } else if self.work.is_empty() {
                break;
            }
        }
        self.fit_within();
        BoundedStep {
            step: std::mem::replace(&mut self.x, DVector::zeros(0)),
            blocking: self.work.len(),
        }
    }

    /// `d` without its components that would move the working rows off their
    /// bounds. The minimiser keeps them there only to its rounding, which an
    /// ill-conditioned system (more rows at a bound than the target leaves
    /// free) makes large.
    fn hold(&self, d: DVector<f64>) -> DVector<f64> {
        let w = self.work.len();
        if w == 0 {
            return d;
        }
        let limits = &self.limits;
        // Rows of different blocks share no coordinate.
        let gram = DMatrix::from_fn(w, w, |i, k| {
            let (a, b) = (&limits[self.work[i]], &limits[self.work[k]]);
            if a.at == b.at {
                a.a.iter().zip(b.a).map(|(x, y)| x * y).sum()
            } else {
                0.0
            }
        });
        let rates = DVector::from_fn(w, |i, _| limits[self.work[i]].dot(&d));
        let Some(y) = gram.lu().solve(&rates) else {
            return d;
        };
        let mut held = d;
        for (&row, v) in self.work.iter().zip(y.iter()) {
            let limit = &limits[row];
            for (c, a) in limit.a.iter().enumerate() {
                held[limit.at + c] -= a * v;
            }
        }
        held
    }

    /// The rows `x` is on (no room left) that the free step would cross.
    fn rows_held_at_start(&self) -> Vec<usize> {
        let tiny = 1e-12 * self.free.norm() * self.tiny_scale;
        (0..self.limits.len())
            .filter(|&k| {
                let limit = &self.limits[k];
                limit.room(self.start) <= tiny && limit.dot(&self.free) > tiny
            })
            .collect()
    }

    /// The last guard against rounding: shorten the step until it is within range.
    fn fit_within(&mut self) {
        let zero = DVector::zeros(self.x.len());
        let (t, _) = self.ratio_test(&zero, &self.x, false);
        self.x *= t;
    }

    /// The minimiser with the working set held as equalities, and its
    /// multipliers with the sign flipped (`None` if the rows are dependent).
    fn equality_minimiser(&mut self) -> Option<(DVector<f64>, DVector<f64>)> {
        if self.work.is_empty() {
            return Some((self.free.clone(), DVector::zeros(0)));
        }
        let len = self.free.len();
        let w = self.work.len();
        for &row in &self.work {
            if !self.h_rows.iter().any(|(held, _)| *held == row) {
                let (j, g) = (self.j, self.g);
                let h_inv = self.h_inv.get_or_insert_with(|| {
                    let mut h = -j.tr_mul(&g.solve(j));
                    for k in 0..len {
                        h[(k, k)] += 1.0;
                    }
                    h
                });
                let limit = &self.limits[row];
                let mut column = DVector::zeros(len);
                for (c, a) in limit.a.iter().enumerate() {
                    column.axpy(*a, &h_inv.column(limit.at + c), 1.0);
                }
                self.h_rows.push((row, column));
            }
        }
        let h_a: Vec<&DVector<f64>> = self
            .work
            .iter()
            .filter_map(|row| {
                self.h_rows
                    .iter()
                    .find(|(held, _)| held == row)
                    .map(|(_, c)| c)
            })
            .collect();
        let m = DMatrix::from_fn(w, w, |i, k| self.limits[self.work[i]].dot(h_a[k]));
        let rhs = DVector::from_fn(w, |i, _| {
            let limit = &self.limits[self.work[i]];
            limit.room(self.start) - limit.dot(&self.free)
        });
        let nu = m.lu().solve(&rhs)?;
        let mut target = self.free.clone();
        for (col, v) in h_a.iter().zip(nu.iter()) {
            target += *col * *v;
        }
        Some((target, nu))
    }

    /// [`ratio_test`] over the rows, the working ones skipped if `skip_work`.
    fn ratio_test(
        &self,
        from: &DVector<f64>,
        d: &DVector<f64>,
        skip_work: bool,
    ) -> (f64, Option<usize>) {
        let held: &[usize] = if skip_work { &self.work } else { &[] };
        let limits = self.limits.iter().copied();
        ratio_test(limits, self.start, from, d, self.tiny_scale, held)
    }
}

/// Longest move from `from` along `d` (at most 1) that stays within range
/// of the step from `start`, and the row (its index in `limits`) that stops
/// it; the rows `held` skipped.
fn ratio_test<'a>(
    limits: impl Iterator<Item = Limit<'a>>,
    start: &DVector<f64>,
    from: &DVector<f64>,
    d: &DVector<f64>,
    tiny_scale: f64,
    held: &[usize],
) -> (f64, Option<usize>) {
    // Rates at rounding level would add rows dependent on the working set.
    let tiny = 1e-12 * d.norm() * tiny_scale;
    let mut best = (1.0, None);
    for (k, limit) in limits.enumerate() {
        let rate = limit.dot(d);
        if rate <= tiny || held.contains(&k) {
            continue;
        }
        let room = limit.room(start) - limit.dot(from);
        let t = room.max(0.0) / rate;
        if t < best.0 {
            best = (t, Some(k));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::robot::Robot;

    fn within(robot: &Robot, kappa: &[[f64; 2]], x: &DVector<f64>) -> bool {
        let moved: Vec<[f64; 2]> = kappa
            .iter()
            .enumerate()
            .map(|(s, k)| [k[0] + x[2 * s], k[1] + x[2 * s + 1]])
            .collect();
        robot.within_bounds(&moved).unwrap()
    }

    #[test]
    fn a_step_within_range_is_the_free_step_and_one_beyond_is_held_at_the_bounds() {
        let mut robot = Robot {
            n_elements: 4,
            ..Robot::default()
        };
        robot.body.sections = 2;
        let muscles = robot.muscles("test").unwrap();
        let bounds = Bounds::muscles(muscles, robot.body.section_length());
        let kappa = [[0.5, -0.2], [0.0, 0.8]];
        assert!(robot.within_bounds(&kappa).unwrap());
        let at = DVector::from_iterator(4, kappa.iter().flatten().copied());
        let j = DMatrix::from_row_slice(
            3,
            4,
            &[1.0, 0.2, 0.5, 0.0, 0.0, 1.0, 0.3, 0.4, 0.1, 0.0, 1.0, 0.7],
        );
        let r = DVector::zeros(4);
        let small = DVector::from_column_slice(&[0.1, 0.0, -0.1]);
        let free = bounds.step(&at, &j, &small, &r, 1e-14).unwrap();
        assert_eq!(free.blocking, 0);
        assert!((&j * &free.step - &small).norm() < 1e-9);
        // Far beyond what the range allows: the step stops on its boundary and
        // still lowers the miss.
        let large = small * 200.0;
        let held = bounds.step(&at, &j, &large, &r, 1e-14).unwrap();
        assert!(held.blocking > 0);
        assert!(within(&robot, &kappa, &held.step));
        assert!((&j * &held.step - &large).norm() < large.norm());
    }

    /// The tension step against every choice of the tensions held at zero:
    /// the one whose equality-constrained minimiser is feasible with
    /// non-negative multipliers is the QP's unique answer. From a start on
    /// the bounds (tendons slack, where the search starts holding them) and
    /// from one inside, the active-set step is that answer.
    #[test]
    fn a_tension_step_from_slack_tendons_is_the_qp_minimiser() {
        use rand::{RngExt, SeedableRng};
        let bounds = Bounds::tensions(None);
        let mut rng = rand::rngs::SmallRng::seed_from_u64(7);
        let m = 6;
        for case in 0..40 {
            let j = DMatrix::from_fn(3, m, |_, _| rng.random_range(-1.0..1.0));
            let x = DVector::from_fn(m, |k, _| {
                if case % 2 == 0 && k % 2 == 0 {
                    0.0
                } else {
                    rng.random_range(0.0..2.0)
                }
            });
            let e = DVector::from_fn(3, |_, _| rng.random_range(-1.0..1.0));
            let r = -&x;
            let c = 1e-2;
            let step = bounds.step(&x, &j, &e, &r, c).unwrap().step;
            // minimise |d - r|^2 + |J d - e|^2 / c with the coordinates in
            // `held` at -x (their tension zero): stationary in the others.
            let mut best: Option<DVector<f64>> = None;
            for mask in 0..(1u32 << m) {
                let held: Vec<bool> = (0..m).map(|k| mask & (1 << k) != 0).collect();
                let h = DMatrix::identity(m, m) + j.transpose() * &j / c;
                let g = &r + j.transpose() * &e / c;
                let free: Vec<usize> = (0..m).filter(|k| !held[*k]).collect();
                let mut d = DVector::from_fn(m, |k, _| if held[k] { -x[k] } else { 0.0 });
                if !free.is_empty() {
                    let hff =
                        DMatrix::from_fn(free.len(), free.len(), |a, b| h[(free[a], free[b])]);
                    let rhs = DVector::from_fn(free.len(), |a, _| {
                        g[free[a]]
                            - (0..m)
                                .filter(|k| held[*k])
                                .map(|k| h[(free[a], k)] * d[k])
                                .sum::<f64>()
                    });
                    let df = hff.lu().solve(&rhs).unwrap();
                    for (a, k) in free.iter().enumerate() {
                        d[*k] = df[a];
                    }
                }
                // Feasible, and each held tension's multiplier pushes it up.
                let gradient = &h * &d - &g;
                let ok = (0..m).all(|k| x[k] + d[k] >= -1e-12)
                    && (0..m).filter(|k| held[*k]).all(|k| gradient[k] >= -1e-10);
                if ok {
                    best = Some(d);
                    break;
                }
            }
            let expected = best.expect("a convex QP has a KKT point");
            assert!(
                (&step - &expected).norm() <= 1e-9 * (1.0 + expected.norm()),
                "case {case}: {step} against {expected}"
            );
        }
    }
}

//! Monotone cubic (PCHIP) interpolation: the 1-D slopes shared by the EA(F) table
//! (`crate::law::AxialTable`) and a tensor-product grid used for stiffness maps sigma(p)
//! (paper 001 eq. 13).
//!
//! Slopes follow Fritsch-Carlson with the Fritsch-Butland weighted harmonic mean inside and
//! the one-sided three-point, shape-preserving estimate at the ends (the rules of scipy's
//! `PchipInterpolator`); two points give a straight line. Each interval's cubic is then
//! monotone, so interpolated values stay between the interval's end values.

use crate::error::{Result, SoftrodError};
use crate::jet::{Jet, RodScalar};

/// PCHIP derivatives at the nodes `x` (strictly increasing, >= 2) of the values `y`. Generic
/// in the values, so that a dual number carries the interpolant's derivative with respect to
/// them (the branches follow the values' real parts).
pub fn pchip_slopes<D: RodScalar>(x: &[f64], y: &[D], m: &mut [D]) {
    let n = x.len();
    let h = |k: usize| x[k + 1] - x[k];
    let d = |k: usize| (y[k + 1] - y[k]) / h(k);
    if n == 2 {
        m[0] = d(0);
        m[1] = d(0);
        return;
    }
    let zero = D::from(0.0);
    for k in 1..n - 1 {
        let (d0, d1) = (d(k - 1), d(k));
        m[k] = if d0.value() * d1.value() > 0.0 {
            let (w1, w2) = (2.0 * h(k) + h(k - 1), h(k) + 2.0 * h(k - 1));
            (d0.recip() * w1 + d1.recip() * w2).recip() * (w1 + w2)
        } else {
            zero
        };
    }
    let end = |h0: f64, h1: f64, d0: D, d1: D| {
        let s = (d0 * (2.0 * h0 + h1) - d1 * h0) / (h0 + h1);
        if s.value() * d0.value() <= 0.0 {
            zero
        } else if d0.value() * d1.value() <= 0.0 && s.value().abs() > 3.0 * d0.value().abs() {
            d0 * 3.0
        } else {
            s
        }
    };
    m[0] = end(h(0), h(1), d(0), d(1));
    m[n - 1] = end(h(n - 2), h(n - 3), d(n - 2), d(n - 3));
}

/// Cubic Hermite value on interval `k` at `q`.
#[inline]
pub fn hermite<D: RodScalar>(x: &[f64], y: &[D], m: &[D], k: usize, q: D) -> D {
    let h = x[k + 1] - x[k];
    let t = (q - x[k]) / h;
    let s = -t + 1.0;
    y[k] + t * t * (-(t * 2.0) + 3.0) * (y[k + 1] - y[k]) + t * s * (s * m[k] - t * m[k + 1]) * h
}

/// Interval of `q` in `x` (clamped to the first/last interval).
#[inline]
pub fn interval(x: &[f64], q: f64) -> usize {
    x[1..x.len() - 1].partition_point(|&v| v <= q)
}

/// Values on a regular grid (one strictly increasing axis per dimension, `width` values per
/// grid point, row-major with the last axis fastest), interpolated by tensor-product PCHIP,
/// last axis first (as scipy's `RegularGridInterpolator(method="pchip")`).
#[derive(Debug, Clone, PartialEq)]
pub struct GridPchip {
    axes: Vec<Vec<f64>>,
    values: Vec<f64>,
    width: usize,
}

impl GridPchip {
    pub fn new(axes: Vec<Vec<f64>>, values: Vec<f64>, width: usize) -> Result<Self> {
        if axes.is_empty() || width == 0 {
            return Err(SoftrodError::invalid(
                "axes",
                axes.len(),
                "a grid needs at least one axis and one value per point",
            ));
        }
        for (k, a) in axes.iter().enumerate() {
            if a.len() < 2 || a.windows(2).any(|w| w[1] <= w[0]) || a.iter().any(|v| !v.is_finite())
            {
                return Err(SoftrodError::invalid(
                    format!("axes[{k}]"),
                    format!("{a:?}"),
                    "must hold at least 2 finite, strictly increasing values",
                ));
            }
        }
        let points: usize = axes.iter().map(Vec::len).product();
        if values.len() != points * width {
            return Err(SoftrodError::invalid(
                "values",
                format!("{} values", values.len()),
                format!("must hold {width} values for each of the {points} grid points"),
            ));
        }
        Ok(GridPchip {
            axes,
            values,
            width,
        })
    }

    /// The grid's axes.
    pub fn axes(&self) -> &[Vec<f64>] {
        &self.axes
    }

    pub fn dims(&self) -> usize {
        self.axes.len()
    }

    /// Values per grid point.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Interpolate at the point `p` (one coordinate per axis, inside the grid; the caller
    /// decides what happens outside) into `out` (`width` values).
    pub fn eval(&self, p: &[f64], out: &mut [f64]) {
        let values = self.interpolate(p);
        out[..self.width].copy_from_slice(&values);
    }

    /// The derivatives of the interpolant at `p` with respect to each coordinate: `out[w][c]`
    /// = d value_w / d p_c (`width` rows of `dims` entries). Exact (forward mode through
    /// the slopes and the Hermite cubics) wherever the interpolant is differentiable; at a
    /// grid node along an axis of 3 or more points it is, there the cubics of both sides
    /// agree in value and slope. Where PCHIP's slope rule switches branch (a sign change of
    /// a secant of the values collapsed so far), the branch that the values' real parts
    /// take.
    pub fn gradient(&self, p: &[f64], out: &mut [Vec<f64>]) {
        for c in 0..self.dims() {
            let q: Vec<Jet<1>> = p
                .iter()
                .enumerate()
                .map(|(i, &v)| {
                    if i == c {
                        Jet::variable(v, 0)
                    } else {
                        Jet::from(v)
                    }
                })
                .collect();
            for (w, v) in self.interpolate(&q).iter().enumerate() {
                out[w][c] = v.eps[0];
            }
        }
    }

    /// The tensor-product interpolation, channel by channel, last first.
    fn interpolate<D: RodScalar>(&self, p: &[D]) -> Vec<D> {
        let mut cur: Vec<D> = self.values.iter().map(|&v| D::from(v)).collect();
        let mut lines: usize = self.values.len() / self.width;
        let zero = D::from(0.0);
        let mut line = Vec::new();
        let mut slopes = Vec::new();
        for (c, x) in self.axes.iter().enumerate().rev() {
            let n = x.len();
            lines /= n;
            let k = interval(x, p[c].value());
            line.resize(n, zero);
            slopes.resize(n, zero);
            let mut next = vec![zero; lines * self.width];
            // cur is (lines, n, width) row-major; collapse its middle axis at p[c].
            for l in 0..lines {
                for w in 0..self.width {
                    for (j, v) in line.iter_mut().enumerate() {
                        *v = cur[(l * n + j) * self.width + w];
                    }
                    pchip_slopes(x, &line, &mut slopes);
                    next[l * self.width + w] = hermite(x, &line, &slopes, k, p[c]);
                }
            }
            cur = next;
        }
        cur.truncate(self.width);
        cur
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A function that is cubic along each axis within the grid is not reproduced by PCHIP
    /// in general, but a multilinear one is exactly (all slopes equal the secants).
    #[test]
    fn grid_reproduces_nodes_and_multilinear_functions() {
        let axes = vec![vec![0.0, 1.0, 3.0], vec![-1.0, 0.5, 2.0, 4.0]];
        let f = |a: f64, b: f64| 2.0 + 0.5 * a - 0.25 * b + 0.1 * a * b;
        let mut values = Vec::new();
        for &a in &axes[0] {
            for &b in &axes[1] {
                values.push(f(a, b));
                values.push(3.0 * f(a, b));
            }
        }
        let g = GridPchip::new(axes, values, 2).unwrap();
        let mut out = [0.0; 2];
        for (a, b) in [(0.0, -1.0), (1.0, 2.0), (3.0, 4.0), (0.3, 0.7), (2.2, 3.9)] {
            g.eval(&[a, b], &mut out);
            assert!((out[0] - f(a, b)).abs() < 1e-13, "({a}, {b}): {}", out[0]);
            assert!((out[1] - 3.0 * f(a, b)).abs() < 1e-13);
        }
    }

    /// The gradient against one-sided differences of `eval` from both sides, on a table
    /// that is not multilinear (so the slopes are PCHIP's own), inside cells and at a node of
    /// a 3-point axis (where the interpolant is C1 but not C2, so a central difference
    /// across it would be first order only).
    #[test]
    fn grid_gradient_matches_one_sided_differences() {
        let axes = vec![vec![0.0, 1.0, 2.5, 4.0], vec![-1.0, 0.5, 2.0]];
        let f = |a: f64, b: f64| 1.0 + (0.8 * a).sin() + 0.3 * b * b + 0.1 * a * b;
        let mut values = Vec::new();
        for &a in &axes[0] {
            for &b in &axes[1] {
                values.extend([f(a, b), 2.0 - f(a, b)]);
            }
        }
        let g = GridPchip::new(axes, values, 2).unwrap();
        let mut grad = vec![vec![0.0; 2]; 2];
        let at = |p: [f64; 2], c: usize, step: f64| {
            let mut q = p;
            q[c] += step;
            let mut out = [0.0; 2];
            g.eval(&q, &mut out);
            out
        };
        // The three-point one-sided difference (-3 f0 + 4 f1 - f2) / 2h stays on one cubic
        // piece; with h = 1e-5 on values of order 1 its error is O(h^2 |f'''|) + O(eps / h),
        // about 1e-10: 1e-8 leaves room for the cubics' third derivatives.
        let h = 1e-5;
        for p in [[0.3, -0.2], [1.7, 1.1], [3.2, 0.5], [2.5, 1.3], [0.9, 1.9]] {
            g.gradient(&p, &mut grad);
            for c in 0..2 {
                for side in [1.0, -1.0] {
                    let (f0, f1, f2) =
                        (at(p, c, 0.0), at(p, c, side * h), at(p, c, side * 2.0 * h));
                    for w in 0..2 {
                        let fd = side * (-3.0 * f0[w] + 4.0 * f1[w] - f2[w]) / (2.0 * h);
                        let got = grad[w][c];
                        assert!(
                            (got - fd).abs() < 1e-8,
                            "{p:?} c={c} w={w} side {side}: {got} vs {fd}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn grid_rejects_bad_shapes() {
        assert!(GridPchip::new(vec![vec![0.0, 1.0]], vec![1.0; 3], 1).is_err());
        assert!(GridPchip::new(vec![vec![1.0, 0.0]], vec![1.0; 2], 1).is_err());
        assert!(GridPchip::new(vec![], vec![], 1).is_err());
    }
}

//! `Jet<N>`: a forward-mode dual number with exactly N derivative directions stored inline.
//!
//! num-dual's `DualSVec64<N>` keeps its derivative in an `Option` so that constants are cheap;
//! on the shooting hot path every state entry carries all six derivatives, and the branches
//! cost a factor of ~3 (measured by `examples/profile_solve.rs`). This type does the same
//! arithmetic (value + first derivatives, exact) without them. It only implements what the
//! rod ODE needs; `RodScalar` is the interface both types (and f64) satisfy.

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jet<const N: usize> {
    pub re: f64,
    pub eps: [f64; N],
}

impl<const N: usize> Jet<N> {
    /// The variable with index `i`: value `re`, derivative e_i.
    pub fn variable(re: f64, i: usize) -> Self {
        let mut eps = [0.0; N];
        eps[i] = 1.0;
        Jet { re, eps }
    }
}

impl<const N: usize> From<f64> for Jet<N> {
    #[inline(always)]
    fn from(re: f64) -> Self {
        Jet { re, eps: [0.0; N] }
    }
}

impl<const N: usize> Add for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Jet {
            re: self.re + o.re,
            eps: std::array::from_fn(|i| self.eps[i] + o.eps[i]),
        }
    }
}

impl<const N: usize> Sub for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Jet {
            re: self.re - o.re,
            eps: std::array::from_fn(|i| self.eps[i] - o.eps[i]),
        }
    }
}

impl<const N: usize> Mul for Jet<N> {
    type Output = Self;
    // The product rule: the derivative part adds two products.
    #[allow(clippy::suspicious_arithmetic_impl)]
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Jet {
            re: self.re * o.re,
            eps: std::array::from_fn(|i| self.eps[i] * o.re + o.eps[i] * self.re),
        }
    }
}

impl<const N: usize> Neg for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Jet {
            re: -self.re,
            eps: self.eps.map(|e| -e),
        }
    }
}

impl<const N: usize> Add<f64> for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: f64) -> Self {
        Jet {
            re: self.re + o,
            eps: self.eps,
        }
    }
}

impl<const N: usize> Sub<f64> for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: f64) -> Self {
        Jet {
            re: self.re - o,
            eps: self.eps,
        }
    }
}

impl<const N: usize> Mul<f64> for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        Jet {
            re: self.re * o,
            eps: self.eps.map(|e| e * o),
        }
    }
}

impl<const N: usize> Div<f64> for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: f64) -> Self {
        Jet {
            re: self.re / o,
            eps: self.eps.map(|e| e / o),
        }
    }
}

impl<const N: usize> AddAssign for Jet<N> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<const N: usize> SubAssign for Jet<N> {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

/// What the rod ODE needs from a scalar: ring arithmetic with itself and with f64.
pub trait RodScalar:
    Copy
    + 'static
    + From<f64>
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + AddAssign
    + SubAssign
{
    /// The value (derivatives dropped).
    fn value(&self) -> f64;
    /// 1 / self.
    fn recip(self) -> Self;
    /// Square root.
    fn sqrt(self) -> Self;
    /// e^self.
    fn exp(self) -> Self;
    /// Natural logarithm.
    fn ln(self) -> Self;
}

impl<const N: usize> RodScalar for Jet<N> {
    #[inline(always)]
    fn value(&self) -> f64 {
        self.re
    }
    #[inline(always)]
    fn recip(self) -> Self {
        let r = 1.0 / self.re;
        let d = -r * r;
        Jet {
            re: r,
            eps: self.eps.map(|e| e * d),
        }
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let r = self.re.sqrt();
        let d = 0.5 / r;
        Jet {
            re: r,
            eps: self.eps.map(|e| e * d),
        }
    }
    #[inline(always)]
    fn exp(self) -> Self {
        let r = self.re.exp();
        Jet {
            re: r,
            eps: self.eps.map(|e| e * r),
        }
    }
    #[inline(always)]
    fn ln(self) -> Self {
        let d = 1.0 / self.re;
        Jet {
            re: self.re.ln(),
            eps: self.eps.map(|e| e * d),
        }
    }
}

impl<T: num_dual::DualNum<Primitive = f64> + Copy> RodScalar for T {
    #[inline(always)]
    fn value(&self) -> f64 {
        self.re()
    }
    #[inline(always)]
    fn recip(self) -> Self {
        num_dual::DualNum::recip(&self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        num_dual::DualNum::sqrt(&self)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        num_dual::DualNum::exp(&self)
    }
    #[inline(always)]
    fn ln(self) -> Self {
        num_dual::DualNum::ln(&self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::DualSVec64;

    /// Jet and num-dual agree exactly on a polynomial of the kind the ODE evaluates.
    #[test]
    fn jet_matches_num_dual() {
        let f = |x: [f64; 3]| -> (f64, [f64; 3]) {
            let a = Jet::<3>::variable(x[0], 0);
            let b = Jet::<3>::variable(x[1], 1);
            let c = Jet::<3>::variable(x[2], 2);
            let y = (a * b - c * 2.0 + 1.5) * (-a) + b * b * c;
            (y.re, y.eps)
        };
        let g = |x: [f64; 3]| {
            let a = DualSVec64::<3>::from_re(x[0]).derivative(0);
            let b = DualSVec64::<3>::from_re(x[1]).derivative(1);
            let c = DualSVec64::<3>::from_re(x[2]).derivative(2);
            (a * b - c * 2.0 + 1.5) * (-a) + b * b * c
        };
        let x = [0.3, -1.7, 2.2];
        let (v, d) = f(x);
        let w = g(x);
        assert_eq!(v, w.re);
        let e = w.eps.0.unwrap();
        for i in 0..3 {
            assert!((d[i] - e[i]).abs() <= 1e-15 * (1.0 + e[i].abs()));
        }
    }
}

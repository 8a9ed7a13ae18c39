//! The forward-mode dual number of the whole core, and the scalar interfaces the models are
//! written for.
//!
//! `Grad<D, N>`: a value and its gradient in exactly N directions, stored inline. The rod
//! uses `Jet<N> = Grad<f64, N>` for its exact Jacobians; the PCC model nests it
//! (`Grad<Grad<f64, N>, N>` carries the Hessian) and builds its time-path jet on it
//! (`crate::pcc::jet`). num-dual's `DualSVec64<N>` keeps its derivative in an `Option` so
//! that constants are cheap; on the shooting hot path every state entry carries all six
//! derivatives, and the branches cost a factor of ~3 (measured by
//! `examples/profile_solve.rs`). This type does the same arithmetic (value + first
//! derivatives, exact) without them.
//!
//! `RodScalar` is what the rod ODE needs of a scalar, `Real` what the PCC kinematics need;
//! f64, num-dual numbers and `Grad` satisfy both. `Coeff` and `StateScalar` name the two
//! scalars of the rod ODE (coefficients and state).

use num_dual::DualNum;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A value and its gradient in N variables.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grad<D, const N: usize> {
    pub re: D,
    pub eps: [D; N],
}

impl<D: Real, const N: usize> Grad<D, N> {
    /// A constant (zero gradient).
    #[inline(always)]
    pub fn constant(re: D) -> Self {
        Grad {
            re,
            eps: [D::from(0.0); N],
        }
    }

    /// Variable number `i`: gradient e_i.
    #[inline(always)]
    pub fn variable(re: D, i: usize) -> Self {
        let mut g = Self::constant(re);
        g.eps[i] = D::from(1.0);
        g
    }

    /// f(self) given f and f' at the value.
    #[inline(always)]
    fn chain(&self, f0: D, f1: D) -> Self {
        Grad {
            re: f0,
            eps: self.eps.map(|e| e * f1),
        }
    }
}

impl<D: Real, const N: usize> From<f64> for Grad<D, N> {
    #[inline(always)]
    fn from(x: f64) -> Self {
        Self::constant(D::from(x))
    }
}

impl<D: Real, const N: usize> Add for Grad<D, N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Grad {
            re: self.re + o.re,
            eps: std::array::from_fn(|i| self.eps[i] + o.eps[i]),
        }
    }
}

impl<D: Real, const N: usize> Sub for Grad<D, N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Grad {
            re: self.re - o.re,
            eps: std::array::from_fn(|i| self.eps[i] - o.eps[i]),
        }
    }
}

impl<D: Real, const N: usize> Mul for Grad<D, N> {
    type Output = Self;
    // The product rule adds.
    #[allow(clippy::suspicious_arithmetic_impl)]
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Grad {
            re: self.re * o.re,
            eps: std::array::from_fn(|i| self.re * o.eps[i] + self.eps[i] * o.re),
        }
    }
}

impl<D: Real, const N: usize> Div for Grad<D, N> {
    type Output = Self;
    #[allow(clippy::suspicious_arithmetic_impl)]
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let inv = D::from(1.0) / o.re;
        let re = self.re * inv;
        Grad {
            re,
            eps: std::array::from_fn(|i| (self.eps[i] - re * o.eps[i]) * inv),
        }
    }
}

impl<D: Real, const N: usize> Neg for Grad<D, N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Grad {
            re: -self.re,
            eps: self.eps.map(|e| -e),
        }
    }
}

impl<D: Real, const N: usize> Add<f64> for Grad<D, N> {
    type Output = Self;
    #[inline(always)]
    fn add(mut self, o: f64) -> Self {
        self.re = self.re + o;
        self
    }
}

impl<D: Real, const N: usize> Sub<f64> for Grad<D, N> {
    type Output = Self;
    #[inline(always)]
    fn sub(mut self, o: f64) -> Self {
        self.re = self.re - o;
        self
    }
}

impl<D: Real, const N: usize> Mul<f64> for Grad<D, N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        Grad {
            re: self.re * o,
            eps: self.eps.map(|e| e * o),
        }
    }
}

impl<D: Real, const N: usize> Div<f64> for Grad<D, N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: f64) -> Self {
        Grad {
            re: self.re / o,
            eps: self.eps.map(|e| e / o),
        }
    }
}

impl<D: Real, const N: usize> AddAssign for Grad<D, N> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<D: Real, const N: usize> SubAssign for Grad<D, N> {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

impl<D: Real, const N: usize> MulAssign<f64> for Grad<D, N> {
    #[inline(always)]
    fn mul_assign(&mut self, o: f64) {
        *self = *self * o;
    }
}

impl<D: Real, const N: usize> Real for Grad<D, N> {
    const NDERIV: usize = D::NDERIV + 1;
    #[inline(always)]
    fn re(&self) -> f64 {
        self.re.re()
    }
    #[inline(always)]
    fn sqrt(&self) -> Self {
        let s = self.re.sqrt();
        self.chain(s, D::from(0.5) / s)
    }
    #[inline(always)]
    fn sin(&self) -> Self {
        self.chain(self.re.sin(), self.re.cos())
    }
    #[inline(always)]
    fn cos(&self) -> Self {
        self.chain(self.re.cos(), -self.re.sin())
    }
}

/// The rod's dual number: a value and N exact first derivatives, in f64.
pub type Jet<const N: usize> = Grad<f64, N>;

/// Scalars the PCC model is written for: f64, num-dual numbers and the model's own
/// fixed-size jets (`super::jet`). Only what the kinematics and forces use.
pub trait Real:
    Copy
    + From<f64>
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign<f64>
{
    /// Highest derivative carried (nilpotency order of the non-real part).
    const NDERIV: usize;
    /// The plain value.
    fn re(&self) -> f64;
    fn sqrt(&self) -> Self;
    fn sin(&self) -> Self;
    fn cos(&self) -> Self;
}

impl<T: DualNum<Primitive = f64> + Copy> Real for T {
    const NDERIV: usize = <T as DualNum>::NDERIV;
    #[inline]
    fn re(&self) -> f64 {
        num_dual::DualStruct::re(self)
    }
    #[inline]
    fn sqrt(&self) -> Self {
        DualNum::sqrt(self)
    }
    #[inline]
    fn sin(&self) -> Self {
        DualNum::sin(self)
    }
    #[inline]
    fn cos(&self) -> Self {
        DualNum::cos(self)
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

impl<const N: usize> RodScalar for Grad<f64, N> {
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

/// Scalar of the coefficients (f64, or a dual number for parameter derivatives).
pub trait Coeff: RodScalar {}
impl<C: RodScalar> Coeff for C {}

/// Scalar of the state.
pub trait StateScalar<C>:
    RodScalar + From<C> + Mul<C, Output = Self> + Add<C, Output = Self>
{
}
impl<C, D> StateScalar<C> for D where
    D: RodScalar + From<C> + Mul<C, Output = D> + Add<C, Output = D>
{
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

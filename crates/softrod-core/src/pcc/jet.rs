//! The PCC model's time-path jet (`Jet<D, N>`): a value, its gradient in q (N), and its
//! first and second derivatives along the time path q + q_t t + q_tt t^2 / 2. This is
//! exactly what the Lagrangian needs for J^T p_tt: p_tt is the second time derivative and J
//! the gradient. The nested `Dual2<DualSVec<D, N>>` also carried the gradients of the rate
//! and acceleration, 2N numbers per scalar that nothing reads: a `Jet<f64, 3>` product costs
//! 13 multiplications against 42. Fixed-size arrays (no `Option`, no allocation, loops the
//! compiler unrolls); elementary functions use the chain rule with the exact derivatives of
//! sin, cos and sqrt. The first-order dual `Grad` is the core's (`crate::jet`).

pub use crate::jet::Grad;
use crate::jet::Real;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// Value, gradient in q, and first and second derivatives along the time path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jet<D, const N: usize> {
    pub re: D,
    pub grad: [D; N],
    /// d/dt.
    pub d1: D,
    /// d^2/dt^2.
    pub d2: D,
}

impl<D: Real, const N: usize> Jet<D, N> {
    #[inline]
    pub fn constant(re: D) -> Self {
        let z = D::from(0.0);
        Jet {
            re,
            grad: [z; N],
            d1: z,
            d2: z,
        }
    }

    /// Coordinate `i` moving as x + v t + a t^2 / 2.
    #[inline]
    pub fn variable(x: D, v: D, a: D, i: usize) -> Self {
        let mut j = Self::constant(x);
        j.grad[i] = D::from(1.0);
        j.d1 = v;
        j.d2 = a;
        j
    }

    /// f(self) given f, f' and f'' at the value.
    #[inline]
    fn chain(&self, f0: D, f1: D, f2: D) -> Self {
        Jet {
            re: f0,
            grad: self.grad.map(|g| g * f1),
            d1: self.d1 * f1,
            d2: self.d2 * f1 + self.d1 * self.d1 * f2,
        }
    }
}

impl<D: Real, const N: usize> From<f64> for Jet<D, N> {
    #[inline]
    fn from(x: f64) -> Self {
        Self::constant(D::from(x))
    }
}

impl<D: Real, const N: usize> Add for Jet<D, N> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Jet {
            re: self.re + o.re,
            grad: std::array::from_fn(|i| self.grad[i] + o.grad[i]),
            d1: self.d1 + o.d1,
            d2: self.d2 + o.d2,
        }
    }
}

impl<D: Real, const N: usize> Sub for Jet<D, N> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Jet {
            re: self.re - o.re,
            grad: std::array::from_fn(|i| self.grad[i] - o.grad[i]),
            d1: self.d1 - o.d1,
            d2: self.d2 - o.d2,
        }
    }
}

impl<D: Real, const N: usize> Mul for Jet<D, N> {
    type Output = Self;
    // The product rule adds.
    #[allow(clippy::suspicious_arithmetic_impl)]
    #[inline]
    fn mul(self, o: Self) -> Self {
        Jet {
            re: self.re * o.re,
            grad: std::array::from_fn(|i| self.re * o.grad[i] + self.grad[i] * o.re),
            d1: self.re * o.d1 + self.d1 * o.re,
            d2: self.re * o.d2 + self.d1 * o.d1 * 2.0 + self.d2 * o.re,
        }
    }
}

impl<D: Real, const N: usize> Div for Jet<D, N> {
    type Output = Self;
    #[allow(clippy::suspicious_arithmetic_impl)]
    #[inline]
    fn div(self, o: Self) -> Self {
        // 1/x: f' = -1/x^2, f'' = 2/x^3.
        let r = D::from(1.0) / o.re;
        let r2 = r * r;
        self * o.chain(r, -r2, r2 * r * 2.0)
    }
}

impl<D: Real, const N: usize> Neg for Jet<D, N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Jet {
            re: -self.re,
            grad: self.grad.map(|g| -g),
            d1: -self.d1,
            d2: -self.d2,
        }
    }
}

impl<D: Real, const N: usize> Add<f64> for Jet<D, N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: f64) -> Self {
        self.re = self.re + o;
        self
    }
}

impl<D: Real, const N: usize> Sub<f64> for Jet<D, N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: f64) -> Self {
        self.re = self.re - o;
        self
    }
}

impl<D: Real, const N: usize> Mul<f64> for Jet<D, N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: f64) -> Self {
        Jet {
            re: self.re * o,
            grad: self.grad.map(|g| g * o),
            d1: self.d1 * o,
            d2: self.d2 * o,
        }
    }
}

impl<D: Real, const N: usize> Div<f64> for Jet<D, N> {
    type Output = Self;
    #[inline]
    fn div(self, o: f64) -> Self {
        Jet {
            re: self.re / o,
            grad: self.grad.map(|g| g / o),
            d1: self.d1 / o,
            d2: self.d2 / o,
        }
    }
}

impl<D: Real, const N: usize> AddAssign for Jet<D, N> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<D: Real, const N: usize> SubAssign for Jet<D, N> {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

impl<D: Real, const N: usize> MulAssign<f64> for Jet<D, N> {
    #[inline]
    fn mul_assign(&mut self, o: f64) {
        *self = *self * o;
    }
}

impl<D: Real, const N: usize> Real for Jet<D, N> {
    const NDERIV: usize = D::NDERIV + 2;
    #[inline]
    fn re(&self) -> f64 {
        self.re.re()
    }
    #[inline]
    fn sqrt(&self) -> Self {
        let s = self.re.sqrt();
        let f1 = D::from(0.5) / s;
        self.chain(s, f1, -(f1 / self.re) * 0.5)
    }
    #[inline]
    fn sin(&self) -> Self {
        let (s, c) = (self.re.sin(), self.re.cos());
        self.chain(s, c, -s)
    }
    #[inline]
    fn cos(&self) -> Self {
        let (s, c) = (self.re.sin(), self.re.cos());
        self.chain(c, -s, -c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_dual::{Dual2, DualSVec};

    /// The jets of f(x) = sin(sqrt(x)) / x * (1 - cos(x)) + x^2 agree with the nested num-dual
    /// numbers they replace, in every part that both carry.
    #[test]
    fn jet_and_grad_match_num_dual() {
        fn f<S: Real>(x: S, y: S) -> S {
            (x.sqrt().sin() / x) * (S::from(1.0) - y.cos()) + x * y * 3.0 - y / 2.0
        }
        let (x0, y0, v, a) = (0.7, 1.3, [0.4, -0.2], [1.1, 0.5]);
        type K = Dual2<DualSVec<f64, 2>>;
        let kv = |z: f64, i: usize| {
            K::new(
                DualSVec::from_re(z).derivative(i),
                DualSVec::from_re(v[i]),
                DualSVec::from_re(a[i]),
            )
        };
        let k = f(kv(x0, 0), kv(y0, 1));
        let j = f(
            Jet::<f64, 2>::variable(x0, v[0], a[0], 0),
            Jet::<f64, 2>::variable(y0, v[1], a[1], 1),
        );
        let g = f(Grad::<f64, 2>::variable(x0, 0), Grad::variable(y0, 1));
        let ke = k.re.eps.0.unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * (1.0 + b.abs());
        assert!(close(j.re, k.re.re) && close(g.re, k.re.re));
        for i in 0..2 {
            assert!(close(j.grad[i], ke[i]) && close(g.eps[i], ke[i]));
        }
        assert!(close(j.d1, k.v1.re) && close(j.d2, k.v2.re));
        assert_eq!(<Jet<Grad<f64, 2>, 2> as Real>::NDERIV, 3);
        assert_eq!(<Grad<Grad<f64, 2>, 2> as Real>::NDERIV, 2);
    }
}

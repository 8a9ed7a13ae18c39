//! LU factorisation with partial (row) pivoting of a banded matrix, in LAPACK's band storage
//! (the algorithm of dgbtf2/dgbtrs). Cost: n kl (kl + ku) to factor and n (2 kl + ku) per
//! solve, linear in n. The collocation Newton (`crate::collocation`) solves its
//! almost-block-diagonal systems with it: partial pivoting is what keeps multiple-shooting
//! and collocation systems stable where the recurrence alone (single shooting) is not.
//!
//! The hot loops are short contiguous axpys; [`simd_dispatch!`] compiles them a second time
//! for AVX2 and picks that copy at run time where the CPU has it. Without FMA the AVX2
//! copy performs the same IEEE operations in the same order, only four lanes at a time, so
//! both copies return bitwise equal results.

/// Inside `impl $ty`, define `pub fn $name(args) -> R` that runs the body `$imp` compiled for AVX2 where the
/// CPU has it (detected at run time, cached by std) and for the baseline target otherwise.
/// `$imp` must be `#[inline(always)]` so that it is compiled into each copy. AVX2 without
/// FMA changes no rounding (Rust never contracts a * b + c), so the copies agree bitwise.
macro_rules! simd_dispatch {
    ($ty:ty: $(#[$m:meta])* $vis:vis fn $name:ident(&$self:ident $(, $a:ident: $t:ty)*) $(-> $r:ty)? => $imp:ident) => {
        $(#[$m])*
        #[inline(never)]
        $vis fn $name(&$self $(, $a: $t)*) $(-> $r)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                unsafe fn avx2(this: &$ty $(, $a: $t)*) $(-> $r)? {
                    this.$imp($($a),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2 (checked just above), the only
                    // requirement of calling a function compiled for it.
                    return unsafe { avx2($self $(, $a)*) };
                }
            }
            $self.$imp($($a),*)
        }
    };
    ($ty:ty: $(#[$m:meta])* $vis:vis fn $name:ident(&mut $self:ident $(, $a:ident: $t:ty)*) $(-> $r:ty)? => $imp:ident) => {
        $(#[$m])*
        #[inline(never)]
        $vis fn $name(&mut $self $(, $a: $t)*) $(-> $r)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                unsafe fn avx2(this: &mut $ty $(, $a: $t)*) $(-> $r)? {
                    this.$imp($($a),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2 (checked just above), the only
                    // requirement of calling a function compiled for it.
                    return unsafe { avx2($self $(, $a)*) };
                }
            }
            $self.$imp($($a),*)
        }
    };
}
pub(crate) use simd_dispatch;

/// A banded n x n matrix with `kl` sub- and `ku` super-diagonals, and after [`factor`] its
/// LU factors (U has kl + ku super-diagonals from the row exchanges).
///
/// [`factor`]: BandedLu::factor
#[derive(Debug, Clone, PartialEq)]
pub struct BandedLu {
    n: usize,
    kl: usize,
    ku: usize,
    /// Column-major band: entry (i, j) at `ab[j * ldab + kl + ku + i - j]`.
    ab: Vec<f64>,
    piv: Vec<usize>,
    /// 1 / U(j, j): the back substitution multiplies (a division's latency would
    /// serialise it; the factors are reused for many solves).
    dinv: Vec<f64>,
    ldab: usize,
}

impl BandedLu {
    /// A zero matrix of size n with the given bandwidths.
    pub fn zeros(n: usize, kl: usize, ku: usize) -> Self {
        let ldab = 2 * kl + ku + 1;
        BandedLu {
            n,
            kl,
            ku,
            ab: vec![0.0; ldab * n],
            piv: vec![0; n],
            dinv: vec![0.0; n],
            ldab,
        }
    }

    pub fn n(&self) -> usize {
        self.n
    }

    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> usize {
        j * self.ldab + self.kl + self.ku + i - j
    }

    /// Set entry (i, j), which must lie inside the band (|i - j| within kl, ku).
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, v: f64) {
        debug_assert!(
            i <= j + self.kl && j <= i + self.ku,
            "({i}, {j}) outside the band"
        );
        let k = self.at(i, j);
        self.ab[k] = v;
    }

    simd_dispatch! { BandedLu:
        /// Factor in place. Returns false if a pivot is exactly zero or not finite
        /// (singular).
        pub fn factor(&mut self) -> bool => factor_impl
    }

    simd_dispatch! { BandedLu:
        /// Solve A x = b in place with the factors.
        pub fn solve(&self, b: &mut [f64]) => solve_impl
    }

    simd_dispatch! { BandedLu:
        /// [`BandedLu::solve`] for two right sides at once, interleaved (`b[2 i + c]` is
        /// row i of side c): the substitutions are chains of dependent updates, so the
        /// second side rides along the first's at little extra cost. Each side gets the
        /// same operations in the same order as [`BandedLu::solve`] (the same numbers).
        pub fn solve2(&self, b: &mut [f64]) => solve2_impl
    }

    #[inline(always)]
    fn factor_impl(&mut self) -> bool {
        let (n, kl, ku) = (self.n, self.kl, self.ku);
        let kv = kl + ku;
        // Fill-in rows above the original band start at zero.
        for j in 0..n {
            for r in 0..kl {
                self.ab[j * self.ldab + r] = 0.0;
            }
        }
        let mut ju = 0usize; // last column touched by U so far
        for j in 0..n {
            let km = kl.min(n - 1 - j);
            // Pivot: the largest |a(i, j)|, i in j..=j+km.
            let mut p = j;
            let mut best = self.ab[self.at(j, j)].abs();
            for i in j + 1..=j + km {
                let a = self.ab[self.at(i, j)].abs();
                if a > best {
                    best = a;
                    p = i;
                }
            }
            self.piv[j] = p;
            if !(best.is_finite() && best > 0.0) {
                return false;
            }
            ju = ju.max((j + ku + p - j).min(n - 1));
            if p != j {
                for c in j..=ju {
                    let (a, b) = (self.at(p, c), self.at(j, c));
                    self.ab.swap(a, b);
                }
            }
            let inv = 1.0 / self.ab[self.at(j, j)];
            for i in j + 1..=j + km {
                let k = self.at(i, j);
                self.ab[k] *= inv;
            }
            for c in j + 1..=ju {
                let ujc = self.ab[self.at(j, c)];
                if ujc != 0.0 {
                    for i in j + 1..=j + km {
                        let l = self.ab[self.at(i, j)];
                        let k = self.at(i, c);
                        self.ab[k] -= l * ujc;
                    }
                }
            }
        }
        let _ = kv;
        for j in 0..n {
            self.dinv[j] = 1.0 / self.ab[self.at(j, j)];
        }
        true
    }

    #[inline(always)]
    fn solve_impl(&self, b: &mut [f64]) {
        let (n, kl) = (self.n, self.kl);
        let kv = self.kl + self.ku;
        let ld = self.ldab;
        for j in 0..n {
            let p = self.piv[j];
            if p != j {
                b.swap(p, j);
            }
            let bj = b[j];
            let lm = kl.min(n - 1 - j);
            if bj != 0.0 && lm > 0 {
                // Column j of L below the diagonal: rows j+1..=j+lm, contiguous.
                let col = &self.ab[j * ld + kv + 1..j * ld + kv + 1 + lm];
                for (bi, l) in b[j + 1..j + 1 + lm].iter_mut().zip(col) {
                    *bi -= l * bj;
                }
            }
        }
        for j in (0..n).rev() {
            b[j] *= self.dinv[j];
            let bj = b[j];
            let i0 = j.saturating_sub(kv);
            if bj != 0.0 && i0 < j {
                // Column j of U above the diagonal: rows i0..j, contiguous.
                let col = &self.ab[j * ld + kv - (j - i0)..j * ld + kv];
                for (bi, u) in b[i0..j].iter_mut().zip(col) {
                    *bi -= u * bj;
                }
            }
        }
    }
}

impl BandedLu {
    #[inline(always)]
    fn solve2_impl(&self, b: &mut [f64]) {
        let (n, kl) = (self.n, self.kl);
        let kv = self.kl + self.ku;
        let ld = self.ldab;
        let b = &mut b[..2 * n];
        // SAFETY: [f64; 2] has f64's alignment and no padding, and the 2 n numbers are
        // n pairs: row i of both sides as one value, so that the updates below are
        // two-lane vector operations (on f64 pairs the loops stayed scalar).
        let b: &mut [[f64; 2]] =
            unsafe { std::slice::from_raw_parts_mut(b.as_mut_ptr().cast::<[f64; 2]>(), n) };
        for j in 0..n {
            let p = self.piv[j];
            if p != j {
                b.swap(p, j);
            }
            let [b0, b1] = b[j];
            let lm = kl.min(n - 1 - j);
            if (b0 != 0.0 || b1 != 0.0) && lm > 0 {
                let col = &self.ab[j * ld + kv + 1..j * ld + kv + 1 + lm];
                for (bi, l) in b[j + 1..j + 1 + lm].iter_mut().zip(col) {
                    *bi = [bi[0] - l * b0, bi[1] - l * b1];
                }
            }
        }
        for j in (0..n).rev() {
            let d = self.dinv[j];
            b[j] = [b[j][0] * d, b[j][1] * d];
            let [b0, b1] = b[j];
            let i0 = j.saturating_sub(kv);
            if (b0 != 0.0 || b1 != 0.0) && i0 < j {
                let col = &self.ab[j * ld + kv - (j - i0)..j * ld + kv];
                for (bi, u) in b[i0..j].iter_mut().zip(col) {
                    *bi = [bi[0] - u * b0, bi[1] - u * b1];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two right sides at once give each side's single solve, to the bit.
    #[test]
    fn two_sides_match_two_solves() {
        let (n, kl, ku) = (19, 4, 3);
        let mut m = BandedLu::zeros(n, kl, ku);
        for i in 0..n {
            for j in i.saturating_sub(kl)..(i + ku + 1).min(n) {
                let v = ((3 * i + 7 * j) % 11) as f64 - 5.0 + if i == j { 0.5 } else { 0.0 };
                m.set(i, j, v);
            }
        }
        assert!(m.factor());
        let b0: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let b1: Vec<f64> = (0..n)
            .map(|i| if i % 3 == 0 { 0.0 } else { i as f64 })
            .collect();
        let mut both: Vec<f64> = (0..2 * n)
            .map(|k| if k % 2 == 0 { b0[k / 2] } else { b1[k / 2] })
            .collect();
        m.solve2(&mut both);
        for (c, b) in [b0, b1].into_iter().enumerate() {
            let mut x = b.clone();
            m.solve(&mut x);
            for i in 0..n {
                assert_eq!(x[i].to_bits(), both[2 * i + c].to_bits());
            }
        }
    }

    /// A random banded system whose leading entries are small, so that pivoting is needed,
    /// solved against a dense LU (nalgebra).
    #[test]
    fn matches_dense_lu_with_pivoting() {
        let (n, kl, ku) = (23, 4, 3);
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let mut dense = nalgebra::DMatrix::<f64>::zeros(n, n);
        let mut band = BandedLu::zeros(n, kl, ku);
        for i in 0..n {
            for j in i.saturating_sub(kl)..=(i + ku).min(n - 1) {
                let v = if i == j { 1e-3 * rnd() } else { rnd() };
                dense[(i, j)] = v;
                band.set(i, j, v);
            }
        }
        let b: Vec<f64> = (0..n).map(|_| rnd()).collect();
        let x_dense = dense
            .clone()
            .lu()
            .solve(&nalgebra::DVector::from_vec(b.clone()))
            .unwrap();
        assert!(band.factor());
        let mut x = b.clone();
        band.solve(&mut x);
        for i in 0..n {
            assert!((x[i] - x_dense[i]).abs() < 1e-10 * (1.0 + x_dense[i].abs()));
        }
        // And the residual of the original system is at round-off.
        let r = &dense * nalgebra::DVector::from_vec(x.clone())
            - nalgebra::DVector::from_vec(b.clone());
        assert!(r.amax() < 1e-12);
        // The dispatched copies (AVX2 where the CPU has it) and the baseline ones agree bit
        // for bit: the same IEEE operations in the same order, no FMA.
        let mut base = BandedLu::zeros(n, kl, ku);
        for i in 0..n {
            for j in i.saturating_sub(kl)..=(i + ku).min(n - 1) {
                base.set(i, j, dense[(i, j)]);
            }
        }
        assert!(base.factor_impl());
        assert_eq!(base, band);
        let mut xb = b.clone();
        base.solve_impl(&mut xb);
        assert_eq!(
            xb.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            x.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }
}

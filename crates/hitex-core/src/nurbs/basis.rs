//! B-spline basis functions and their derivatives.

use super::Real;

/// Highest supported degree (arrays below are sized for it).
pub const MAX_DEGREE: usize = 15;
const W: usize = MAX_DEGREE + 1;

/// The `p + 1` non-zero basis functions `N[span−p..=span, p](u)` by the
/// triangular scheme (A2.2); written into `out[..=p]`.
pub fn basis_funs<T: Real>(span: usize, u: T, p: usize, knots: &[T], out: &mut [T; W]) {
    let mut left = [T::ZERO; W];
    let mut right = [T::ZERO; W];
    out[0] = T::ONE;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = T::ZERO;
        for r in 0..j {
            let temp = out[r] / (right[r + 1] + left[j - r]);
            out[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        out[j] = saved;
    }
}

/// Basis functions and their derivatives up to order `n ≤ 2` (A2.3), sharing
/// one triangular table: `ders[k][r]` is the k-th derivative of
/// `N[span−p+r, p](u)`.
pub fn ders_basis_funs<T: Real>(span: usize, u: T, p: usize, n: usize, knots: &[T]) -> [[T; W]; 3] {
    let n = n.min(2).min(p);
    // triangular basis table: ndu[j][r] functions (upper), knot differences (lower)
    let mut ndu = [[T::ZERO; W]; W];
    let mut left = [T::ZERO; W];
    let mut right = [T::ZERO; W];
    ndu[0][0] = T::ONE;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = T::ZERO;
        for r in 0..j {
            ndu[j][r] = right[r + 1] + left[j - r];
            let temp = ndu[r][j - 1] / ndu[j][r];
            ndu[r][j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j][j] = saved;
    }
    let mut ders = [[T::ZERO; W]; 3];
    for j in 0..=p {
        ders[0][j] = ndu[j][p];
    }
    // derivatives (eq. 2.9)
    let mut a = [[T::ZERO; W]; 2];
    for r in 0..=p {
        let (mut s1, mut s2) = (0usize, 1usize);
        a[0][0] = T::ONE;
        for k in 1..=n {
            let mut d = T::ZERO;
            let rk = r as isize - k as isize;
            let pk = p - k;
            if r >= k {
                a[s2][0] = a[s1][0] / ndu[pk + 1][rk as usize];
                d = a[s2][0] * ndu[rk as usize][pk];
            }
            let j1 = if rk >= -1 { 1 } else { (-rk) as usize };
            let j2 = if (r as isize - 1) <= pk as isize { k - 1 } else { p - r };
            for j in j1..=j2 {
                let idx = (rk + j as isize) as usize;
                a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][idx];
                d += a[s2][j] * ndu[idx][pk];
            }
            if r <= pk {
                a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
                d += a[s2][k] * ndu[r][pk];
            }
            ders[k][r] = d;
            std::mem::swap(&mut s1, &mut s2);
        }
    }
    // multiply by p!/(p−k)!
    let mut f = p;
    for (k, row) in ders.iter_mut().enumerate().take(n + 1).skip(1) {
        let fk = T::from_f64(f as f64);
        for v in row.iter_mut().take(p + 1) {
            *v = *v * fk;
        }
        f *= p - k;
    }
    ders
}

#[cfg(test)]
mod tests {
    use super::super::knots::find_span;
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn book_example_2_3() {
        // U = {0,0,0,1,2,3,4,4,5,5,5}, p = 2, u = 5/2: N2,2 = 1/8, N3,2 = 6/8, N4,2 = 1/8
        let u = [0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 4.0, 5.0, 5.0, 5.0];
        let span = find_span(7, 2, 2.5, &u);
        let mut n = [0.0; W];
        basis_funs(span, 2.5, 2, &u, &mut n);
        assert_eq!(&n[..3], &[0.125, 0.75, 0.125]);
        let d = ders_basis_funs(span, 2.5, 2, 2, &u);
        assert_eq!(&d[0][..3], &[0.125, 0.75, 0.125]);
        // N' = (−1/2, 0, 1/2), N'' = (1, −2, 1)
        assert_eq!(&d[1][..3], &[-0.5, 0.0, 0.5]);
        assert_eq!(&d[2][..3], &[1.0, -2.0, 1.0]);
    }

    fn knot_vector(p: usize, interior: &[f64]) -> Vec<f64> {
        let mut k = vec![0.0; p + 1];
        let mut inner: Vec<f64> = interior.iter().map(|x| x.clamp(0.01, 0.99)).collect();
        inner.sort_by(|a, b| a.total_cmp(b));
        k.extend(inner);
        k.extend(vec![1.0; p + 1]);
        k
    }

    proptest! {
        #[test]
        fn partition_of_unity_and_derivatives(p in 1usize..=9, interior in proptest::collection::vec(0.0f64..1.0, 0..8), u in 0.0f64..=1.0) {
            let k = knot_vector(p, &interior);
            let n = k.len() - p - 2;
            let span = find_span(n, p, u, &k);
            let d = ders_basis_funs(span, u, p, 2, &k);
            let sum: f64 = d[0][..=p].iter().sum();
            prop_assert!((sum - 1.0).abs() < 1e-12, "sum {sum}");
            prop_assert!(d[0][..=p].iter().all(|&x| x >= -1e-15));
            // derivatives of a partition of unity sum to zero
            let d1: f64 = d[1][..=p].iter().sum();
            prop_assert!(d1.abs() < 1e-8 * (1.0 + d[1][..=p].iter().map(|x| x.abs()).sum::<f64>()));
            // basis_funs agrees with the table
            let mut b = [0.0; W];
            basis_funs(span, u, p, &k, &mut b);
            for r in 0..=p {
                prop_assert!((b[r] - d[0][r]).abs() < 1e-14);
            }
        }

        #[test]
        fn first_derivative_matches_central_difference(p in 1usize..=7, interior in proptest::collection::vec(0.05f64..0.95, 0..5), u in 0.02f64..0.98) {
            let k = knot_vector(p, &interior);
            let n = k.len() - p - 2;
            // stay away from knots where derivatives jump
            let h = 1e-6;
            prop_assume!(k.iter().all(|&x| (x - u).abs() > 10.0 * h));
            let span = find_span(n, p, u, &k);
            prop_assume!(find_span(n, p, u - h, &k) == span && find_span(n, p, u + h, &k) == span);
            let d = ders_basis_funs(span, u, p, 2, &k);
            let (mut a, mut b) = ([0.0; W], [0.0; W]);
            basis_funs(span, u + h, p, &k, &mut a);
            basis_funs(span, u - h, p, &k, &mut b);
            for r in 0..=p {
                let fd = (a[r] - b[r]) / (2.0 * h);
                prop_assert!((fd - d[1][r]).abs() < 1e-4 * (1.0 + d[1][r].abs()), "r {r}: fd {fd} vs {}", d[1][r]);
            }
        }
    }
}

/// Basis functions with first and second derivatives as the paper computes
/// them (seed 004, eq. (6)): the triangular scheme of A2.2 keeps the rows of
/// degree p − 2 and p − 1, and the derivatives follow from
/// `N'_{i,p} = p (N_{i,p−1}/(u_{i+p} − u_i) − N_{i+1,p−1}/(u_{i+p+1} − u_{i+1}))`,
/// applied twice for `N''`. Every division is by a knot difference, taken
/// as a multiplication by its reciprocal (a function of the span alone,
/// which block programs compute once for many parameters). Same values as
/// [`ders_basis_funs`] to rounding; this is the form `nurbs.wgsl` mirrors. Returns `(N, N', N'')` for r = 0..=p; `N''`
/// only when `second` is set (zeros otherwise).
pub fn basis_ders_paper<T: Real>(span: usize, u: T, p: usize, knots: &[T], second: bool) -> [[T; W]; 3] {
    triangle::<T, W>(span, u, p, knots, second)
}

/// The triangular scheme with eq. (6) derivatives in arrays of `N ≥ p + 1`
/// entries: shared by the any-degree form (`N` = 16, p at run time) and the
/// prepared-degree form (`N` = p + 1, p a constant after inlining).
#[inline(always)]
fn triangle<T: Real, const N: usize>(span: usize, u: T, p: usize, knots: &[T], second: bool) -> [[T; N]; 3] {
    let mut n = [T::ZERO; N];
    let mut left = [T::ZERO; N];
    let mut right = [T::ZERO; N];
    let mut row_p1 = [T::ZERO; N]; // N_{span−p+1+r, p−1}, r = 0..p−1
    let mut row_p2 = [T::ZERO; N]; // N_{span−p+2+r, p−2}, r = 0..p−2
    n[0] = T::ONE;
    if p == 1 {
        row_p1[0] = T::ONE;
    }
    if p == 2 {
        row_p2[0] = T::ONE;
    }
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = T::ZERO;
        for r in 0..j {
            // right[r + 1] + left[j − r] is the knot difference
            // u_{span+r+1} − u_{span+1+r−j} (eq. 2's denominator, which u
            // cancels from): its reciprocal depends on the span alone, so a
            // program evaluating many parameters of one span computes it once
            let temp = n[r] * (T::ONE / (knots[span + r + 1] - knots[span + 1 + r - j]));
            n[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        n[j] = saved;
        if j + 2 == p {
            row_p2 = n;
        }
        if j + 1 == p {
            row_p1 = n;
        }
    }
    // derivatives of degree `deg` from the row of degree deg − 1 (eq. 6):
    // lower[r] = N_{first + r, deg − 1}; result[r] = N'_{first − 1 + r, deg}
    let deriv = |deg: usize, lower: &[T; N], first: usize| -> [T; N] {
        let mut d = [T::ZERO; N];
        let fdeg = T::from_f64(deg as f64);
        for r in 0..=deg {
            let i = first + r - 1;
            let mut v = T::ZERO;
            if r >= 1 {
                let den = knots[i + deg] - knots[i];
                if den > T::ZERO {
                    v += lower[r - 1] * (T::ONE / den);
                }
            }
            if r < deg {
                let den = knots[i + deg + 1] - knots[i + 1];
                if den > T::ZERO {
                    v -= lower[r] * (T::ONE / den);
                }
            }
            d[r] = fdeg * v;
        }
        d
    };
    let mut out = [[T::ZERO; N]; 3];
    out[0] = n;
    out[1] = deriv(p, &row_p1, span + 1 - p);
    if second && p >= 2 {
        // N'_{·, p−1} from the row of degree p − 2, then N'' from it
        let d1 = deriv(p - 1, &row_p2, span + 2 - p);
        out[2] = deriv(p, &d1, span + 1 - p);
    }
    out
}

#[cfg(test)]
mod paper_tests {
    use super::super::knots::find_span;
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn paper_form_equals_a2_3(p in 1usize..=9, interior in proptest::collection::vec(0.01f64..0.99, 0..8), u in 0.0f64..=1.0) {
            let mut k = vec![0.0; p + 1];
            let mut inner = interior.clone();
            inner.sort_by(|a, b| a.total_cmp(b));
            k.extend(inner);
            k.extend(vec![1.0; p + 1]);
            let n = k.len() - p - 2;
            let span = find_span(n, p, u, &k);
            let a = ders_basis_funs(span, u, p, 2, &k);
            let b = basis_ders_paper(span, u, p, &k, true);
            for d in 0..3 {
                let scale = 1.0 + a[d][..=p].iter().map(|x| x.abs()).fold(0.0, f64::max);
                for r in 0..=p {
                    prop_assert!((a[d][r] - b[d][r]).abs() < 1e-9 * scale, "d{d} r{r}: {} vs {}", a[d][r], b[d][r]);
                }
            }
        }
    }
}

/// [`basis_ders_paper`] specialised for one degree `P` known at compile time:
/// the same steps, with every loop bound a constant, so the compiler emits the
/// straight-line code the paper writes by hand for each prepared degree
/// (`nurbs.wgsl` has the cubic twin `basis3`). `N` must be `P + 1`.
pub fn basis_ders_fixed<T: Real, const P: usize, const N: usize>(
    span: usize,
    u: T,
    knots: &[T],
    second: bool,
) -> [[T; N]; 3] {
    debug_assert_eq!(N, P + 1);
    triangle::<T, N>(span, u, P, knots, second)
}

#[cfg(test)]
mod fixed_tests {
    use super::super::knots::find_span;
    use super::*;

    #[test]
    fn fixed_quintic_equals_the_generic_form() {
        let k = [0.0f32, 0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 0.35, 0.8, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        for i in 0..=100 {
            let u = i as f32 / 100.0;
            let span = find_span(8, 5, u, &k);
            let a = basis_ders_paper(span, u, 5, &k, true);
            let b = basis_ders_fixed::<f32, 5, 6>(span, u, &k, true);
            for d in 0..3 {
                for r in 0..6 {
                    assert_eq!(a[d][r], b[d][r], "u {u} d{d} r{r}");
                }
            }
        }
    }

    #[test]
    fn fixed_cubic_equals_the_generic_form() {
        let k = [0.0f32, 0.0, 0.0, 0.0, 0.2, 0.45, 0.5, 1.0, 1.0, 1.0, 1.0];
        for i in 0..=100 {
            let u = i as f32 / 100.0;
            let span = find_span(6, 3, u, &k);
            let a = basis_ders_paper(span, u, 3, &k, true);
            let b = basis_ders_fixed::<f32, 3, 4>(span, u, &k, true);
            for d in 0..3 {
                for r in 0..4 {
                    assert_eq!(a[d][r], b[d][r], "u {u} d{d} r{r}");
                }
            }
        }
    }
}

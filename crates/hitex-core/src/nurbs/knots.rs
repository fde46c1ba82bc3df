//! Knot vectors: validation and span search.

use super::{NurbsError, Real};

/// Checks a knot vector for `count` control points of degree `p`:
/// `count + p + 1` finite, non-decreasing knots with a non-empty parameter
/// range `[U[p], U[count]]`.
pub fn validate_knots(dir: &'static str, knots: &[f64], count: usize, p: usize) -> Result<(), NurbsError> {
    if count < p + 1 {
        return Err(NurbsError::Counts {
            dir,
            message: format!("{count} control points cannot carry degree {p} (need ≥ {})", p + 1),
        });
    }
    if knots.len() != count + p + 1 {
        return Err(NurbsError::Counts {
            dir,
            message: format!("{} knots for {count} control points of degree {p} (need {})", knots.len(), count + p + 1),
        });
    }
    if let Some(i) = knots.iter().position(|k| !k.is_finite()) {
        return Err(NurbsError::Knots { dir, message: format!("knot {i} is not finite ({})", knots[i]) });
    }
    if let Some(i) = knots.iter().position(|k| k.abs() > super::surface::MAX_MAGNITUDE) {
        return Err(NurbsError::Knots { dir, message: format!("knot {i} ({:e}) is beyond ±1e150", knots[i]) });
    }
    if let Some(i) = knots.windows(2).position(|w| w[1] < w[0]) {
        return Err(NurbsError::Knots {
            dir,
            message: format!("knot {} ({}) is less than knot {i} ({})", i + 1, knots[i + 1], knots[i]),
        });
    }
    if knots[count] <= knots[p] {
        return Err(NurbsError::Knots {
            dir,
            message: format!("empty parameter range [{}, {}]", knots[p], knots[count]),
        });
    }
    Ok(())
}

/// The knot span index `i` with `U[i] ≤ u < U[i+1]` (A2.1), for `n + 1`
/// control points of degree `p`; `u` at or beyond the end of the range gives
/// the last non-empty span `n` (the end case `m − p − 1`), at or before the
/// start the first span `p`. Binary search: O(log n).
pub fn find_span<T: Real>(n: usize, p: usize, u: T, knots: &[T]) -> usize {
    if u >= knots[n + 1] {
        // end case: the last span that is not empty
        let mut s = n;
        while s > p && knots[s] >= knots[s + 1] {
            s -= 1;
        }
        return s;
    }
    if u <= knots[p] {
        let mut s = p;
        while s < n && knots[s + 1] <= knots[s] {
            s += 1;
        }
        return s;
    }
    let (mut low, mut high) = (p, n + 1);
    let mut mid = (low + high) / 2;
    while u < knots[mid] || u >= knots[mid + 1] {
        if u < knots[mid] {
            high = mid
        } else {
            low = mid
        }
        mid = (low + high) / 2;
    }
    mid
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_by_hand() {
        // NURBS Book Ex2.3: U = {0,0,0,1,2,3,4,4,5,5,5}, p = 2, n = 7
        let u = [0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 4.0, 5.0, 5.0, 5.0];
        assert_eq!(find_span(7, 2, 2.5, &u), 4);
        assert_eq!(find_span(7, 2, 0.0, &u), 2);
        assert_eq!(find_span(7, 2, 0.999, &u), 2);
        assert_eq!(find_span(7, 2, 1.0, &u), 3);
        assert_eq!(find_span(7, 2, 4.0, &u), 7);
        // end case u = u_m: span m − p − 1 = 10 − 2 − 1 = 7
        assert_eq!(find_span(7, 2, 5.0, &u), 7);
        assert_eq!(find_span(7, 2, 9.0, &u), 7);
        assert_eq!(find_span(7, 2, -1.0, &u), 2);
        // f32 agrees
        let uf: Vec<f32> = u.iter().map(|&k| k as f32).collect();
        assert_eq!(find_span(7, 2, 2.5f32, &uf), 4);
    }

    #[test]
    fn validation_names_the_problem() {
        let ok = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
        assert!(validate_knots("u", &ok, 4, 3).is_ok());
        assert!(validate_knots("u", &ok, 5, 3).unwrap_err().to_string().contains("8 knots"));
        assert!(validate_knots("u", &ok, 2, 3).is_err());
        let dec = [0.0, 0.0, 0.0, 0.0, 1.0, 0.5, 1.0, 1.0];
        assert!(validate_knots("v", &dec, 4, 3).unwrap_err().to_string().contains("knot 5"));
        let nan = [0.0, 0.0, 0.0, f64::NAN, 1.0, 1.0, 1.0, 1.0];
        assert!(validate_knots("v", &nan, 4, 3).unwrap_err().to_string().contains("not finite"));
        let flat = [0.0; 8];
        assert!(validate_knots("v", &flat, 4, 3).unwrap_err().to_string().contains("empty"));
    }
}

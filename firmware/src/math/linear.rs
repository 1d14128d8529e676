//! Small dense linear solvers in `f64` from basic operations only (see [`super::scalar`] for why),
//! so that the host and the Cortex-M4F solve to the same bits.

use super::scalar::{abs_f64, max_f64, positive};

/// Gauss-Jordan elimination with partial pivoting of a 5x5 system given as an augmented
/// 5x6 matrix (the right-hand side in column 5; the matrix is overwritten). `None` if a pivot
/// falls below 1e-12 of the largest diagonal entry, or the solution is not finite.
#[allow(clippy::indexing_slicing)] // row and column indices count over the 5 x 6 array
pub fn solve5(a: &mut [[f64; 6]; 5]) -> Option<[f64; 5]> {
    let mut scale: f64 = 0.0;
    for (i, row) in a.iter().enumerate() {
        scale = max_f64(scale, abs_f64(row[i]));
    }
    if !positive(scale) || !scale.is_finite() {
        return None;
    }
    let tiny = scale * 1e-12;
    for col in 0..5 {
        // Pivot: the largest |entry| in this column at or below the diagonal.
        let mut pivot_row = col;
        for row in col + 1..5 {
            if abs_f64(a[row][col]) > abs_f64(a[pivot_row][col]) {
                pivot_row = row;
            }
        }
        if !positive(abs_f64(a[pivot_row][col]) - tiny) {
            return None;
        }
        a.swap(col, pivot_row);
        let pivot_values = a[col];
        for (row, values) in a.iter_mut().enumerate() {
            if row == col {
                continue;
            }
            let factor = values[col] / pivot_values[col];
            for (v, p) in values.iter_mut().zip(pivot_values.iter()).skip(col) {
                *v -= factor * p;
            }
        }
    }
    let mut x = [0.0; 5];
    for (i, (xi, row)) in x.iter_mut().zip(a.iter()).enumerate() {
        *xi = row[5] / row[i];
    }
    if x.iter().all(|v| v.is_finite()) {
        Some(x)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A permuted, scaled system with a known solution (pivoting needed: a zero diagonal),
    /// and a singular one.
    #[test]
    fn solves_and_refuses() {
        let want = [1.0, -2.0, 0.5, 3.0, -0.25];
        let m = [
            [0.0, 2.0, 1.0, 0.0, 1.0],
            [4.0, 0.0, 0.0, 1.0, 0.0],
            [1.0, 1.0, 5.0, 0.0, 2.0],
            [0.0, 3.0, 0.0, 7.0, 1.0],
            [2.0, 0.0, 1.0, 1.0, 6.0],
        ];
        let mut a = [[0.0; 6]; 5];
        for (row, m_row) in a.iter_mut().zip(m.iter()) {
            row[..5].copy_from_slice(m_row);
            row[5] = m_row.iter().zip(want.iter()).map(|(p, q)| p * q).sum();
        }
        let x = solve5(&mut a).expect("regular");
        for (got, want) in x.iter().zip(want.iter()) {
            assert!((got - want).abs() < 1e-12, "{x:?}");
        }
        let mut singular = [[1.0; 6]; 5];
        assert_eq!(solve5(&mut singular), None);
    }
}

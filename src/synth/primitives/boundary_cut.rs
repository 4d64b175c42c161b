//! Minimum-error boundary cut by dynamic programming (Efros–Freeman; docs/methods.md B3).
//!
//! The cut decides, inside an overlap, which pixels keep the old content and which take the new
//! block, so that the transition follows the path where the two agree best.

/// Vertical cut through a `rows × cols` error surface (row-major): returns the cut column of every
/// row. Pixels strictly left of the cut keep the old content; on and right of it take the new block.
pub fn vertical_cut(error: &[u32], rows: usize, cols: usize) -> Vec<usize> {
    assert_eq!(error.len(), rows * cols, "error surface size");
    assert!(rows > 0 && cols > 0, "empty error surface");
    let mut cost: Vec<u64> = error[..cols].iter().map(|&e| e as u64).collect();
    cost.reserve(rows * cols - cols);
    for i in 1..rows {
        let prev = (i - 1) * cols;
        for j in 0..cols {
            let mut best = cost[prev + j];
            if j > 0 {
                best = best.min(cost[prev + j - 1]);
            }
            if j + 1 < cols {
                best = best.min(cost[prev + j + 1]);
            }
            cost.push(error[i * cols + j] as u64 + best);
        }
    }
    let last = (rows - 1) * cols;
    let mut j = (0..cols).min_by_key(|&j| (cost[last + j], j)).expect("cols > 0");
    let mut cut = vec![0; rows];
    cut[rows - 1] = j;
    for i in (0..rows - 1).rev() {
        let base = i * cols;
        // Prefer straight up, then up-left, then up-right on ties.
        let mut best_j = j;
        let mut best = cost[base + j];
        if j > 0 && cost[base + j - 1] < best {
            best = cost[base + j - 1];
            best_j = j - 1;
        }
        if j + 1 < cols && cost[base + j + 1] < best {
            best_j = j + 1;
        }
        j = best_j;
        cut[i] = j;
    }
    cut
}

/// Horizontal cut through a `rows × cols` error surface: returns the cut row of every column.
/// Pixels strictly above the cut keep the old content.
pub fn horizontal_cut(error: &[u32], rows: usize, cols: usize) -> Vec<usize> {
    let mut transposed = vec![0u32; rows * cols];
    for i in 0..rows {
        for j in 0..cols {
            transposed[j * rows + i] = error[i * cols + j];
        }
    }
    vertical_cut(&transposed, cols, rows)
}

/// Total error along a vertical cut.
pub fn vertical_cut_cost(error: &[u32], cols: usize, cut: &[usize]) -> u64 {
    cut.iter().enumerate().map(|(i, &j)| error[i * cols + j] as u64).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_surface_cuts_straight_down_column_zero() {
        assert_eq!(vertical_cut(&[0; 12], 4, 3), vec![0, 0, 0, 0]);
        assert_eq!(horizontal_cut(&[0; 12], 4, 3), vec![0, 0, 0]);
    }

    #[test]
    fn finds_a_cheap_winding_corridor() {
        // Costly everywhere except a corridor that moves one column per row.
        let rows = 6;
        let cols = 5;
        let corridor = [3usize, 2, 1, 1, 2, 3];
        let mut e = vec![1000u32; rows * cols];
        for (i, &j) in corridor.iter().enumerate() {
            e[i * cols + j] = 1;
        }
        let cut = vertical_cut(&e, rows, cols);
        assert_eq!(cut, corridor);
        assert_eq!(vertical_cut_cost(&e, cols, &cut), 6);
    }

    #[test]
    fn cut_is_connected_and_minimal_against_brute_force() {
        // Every 8-connected top-to-bottom path on a small surface; the DP must hit the minimum.
        let rows = 5;
        let cols = 4;
        let e: Vec<u32> = (0..rows * cols).map(|k| ((k * 37 + 11) % 17) as u32).collect();
        let cut = vertical_cut(&e, rows, cols);
        for w in cut.windows(2) {
            assert!(w[0].abs_diff(w[1]) <= 1);
        }
        fn best(e: &[u32], cols: usize, rows: usize, i: usize, j: usize) -> u64 {
            let here = e[i * cols + j] as u64;
            if i + 1 == rows {
                return here;
            }
            let mut m = u64::MAX;
            for nj in j.saturating_sub(1)..=(j + 1).min(cols - 1) {
                m = m.min(best(e, cols, rows, i + 1, nj));
            }
            here + m
        }
        let brute = (0..cols).map(|j| best(&e, cols, rows, 0, j)).min().unwrap();
        assert_eq!(vertical_cut_cost(&e, cols, &cut), brute);
    }

    #[test]
    fn horizontal_cut_is_the_transpose() {
        let rows = 3;
        let cols = 6;
        let mut e = vec![50u32; rows * cols];
        for j in 0..cols {
            e[2 * cols + j] = 0; // cheapest along the bottom row
        }
        assert_eq!(horizontal_cut(&e, rows, cols), vec![2; cols]);
    }
}

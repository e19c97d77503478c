//! Cross products of long columns, `A^T B`, by row blocks.
//!
//! A fit's normal equations need the products of every pair of its basis columns. Taken one
//! pair at a time (a dot product over the whole record), each product reads two columns from
//! memory: on a long record, whose columns do not fit in the caches, the fit is then bound by
//! memory traffic (m^2 / 2 column reads for m columns) and its time grows faster than the
//! record. Here the record is cut into blocks of [`BLOCK_ROWS`] rows; each block's columns are
//! copied into a small contiguous matrix and multiplied by a cache-blocked matrix product
//! (`matrixmultiply`'s dgemm), so every column is read once per product.
//!
//! The blocks are fixed by the record's length alone, grouped into chunks of [`CHUNK_BLOCKS`]
//! summed in order inside a chunk, and the chunks' sums are added in order: the result is the
//! same whatever the thread count. (The order differs from a dot product over the whole record:
//! the sums agree to rounding, not bit for bit.)

use nalgebra::DMatrix;
use rayon::prelude::*;
use std::ops::Range;

/// Rows per block: a block of 64 columns is 2 MB (in the caches of current processors).
pub const BLOCK_ROWS: usize = 4096;

/// Blocks summed in order by one task (a task is the unit of parallel work).
pub const CHUNK_BLOCKS: usize = 16;

/// The sum over the record's row blocks of `block(rows)`, each an `r x c` matrix: blocks summed
/// in order within fixed chunks, chunks in parallel, their sums added in order.
pub fn sum_by_row_blocks<F>(n: usize, r: usize, c: usize, block: F) -> DMatrix<f64>
where
    F: Fn(Range<usize>) -> DMatrix<f64> + Sync,
{
    let chunk = BLOCK_ROWS * CHUNK_BLOCKS;
    let chunks: Vec<Range<usize>> = (0..n.div_ceil(chunk))
        .map(|k| k * chunk..((k + 1) * chunk).min(n))
        .collect();
    let sums: Vec<DMatrix<f64>> = chunks
        .into_par_iter()
        .map(|rows| {
            let mut s = DMatrix::zeros(r, c);
            let mut at = rows.start;
            while at < rows.end {
                let end = (at + BLOCK_ROWS).min(rows.end);
                s += block(at..end);
                at = end;
            }
            s
        })
        .collect();
    sums.into_iter()
        .fold(DMatrix::zeros(r, c), |acc, s| acc + s)
}

/// The rows `rows` of the columns `cols`, as a contiguous column-major matrix.
pub fn block_of(cols: &[&[f64]], rows: Range<usize>) -> DMatrix<f64> {
    let len = rows.len();
    let mut data = Vec::with_capacity(len * cols.len());
    for c in cols {
        data.extend_from_slice(&c[rows.clone()]);
    }
    DMatrix::from_vec(len, cols.len(), data)
}

/// `A^T B` of two blocks with the same rows: one matrix product (`matrixmultiply`'s dgemm,
/// reading `a` through transposed strides, no copy).
pub fn tr_mul_block(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let (rows, k) = a.shape();
    let c = b.ncols();
    assert_eq!(b.nrows(), rows, "blocks of different rows");
    let mut out = DMatrix::zeros(k, c);
    if rows == 0 || k == 0 || c == 0 {
        return out;
    }
    let (rows_i, k_i) = (rows as isize, k as isize);
    // SAFETY: a is rows x k and b rows x c, column-major and contiguous; A^T (k x rows) is read
    // with row stride `rows` and column stride 1, B with (1, rows), and out (k x c,
    // column-major) written with (1, k): every index stays inside its buffer.
    unsafe {
        matrixmultiply::dgemm(
            k,
            rows,
            c,
            1.0,
            a.as_ptr(),
            rows_i,
            1,
            b.as_ptr(),
            1,
            rows_i,
            0.0,
            out.as_mut_ptr(),
            1,
            k_i,
        );
    }
    out
}

/// `A^T B` for columns `a` and `b` of one length `n` (`a.len() x b.len()`).
pub fn cross_products(a: &[&[f64]], b: &[&[f64]]) -> DMatrix<f64> {
    let n = a.first().or(b.first()).map_or(0, |c| c.len());
    debug_assert!(a.iter().chain(b).all(|c| c.len() == n));
    sum_by_row_blocks(n, a.len(), b.len(), |rows| {
        tr_mul_block(&block_of(a, rows.clone()), &block_of(b, rows))
    })
}

/// `A^T A` for columns `a` of one length: the upper triangle computed, mirrored (exactly
/// symmetric).
pub fn gram(a: &[&[f64]]) -> DMatrix<f64> {
    let n = a.first().map_or(0, |c| c.len());
    let k = a.len();
    let mut g = sum_by_row_blocks(n, k, k, |rows| {
        let x = block_of(a, rows);
        tr_mul_block(&x, &x)
    });
    for i in 0..k {
        for j in 0..i {
            g[(i, j)] = g[(j, i)];
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    fn columns(k: usize, n: usize) -> Vec<Vec<f64>> {
        (0..k)
            .map(|i| {
                (0..n)
                    .map(|t| ((t * (i + 3)) as f64 * 0.37).sin() + i as f64 * 0.1)
                    .collect()
            })
            .collect()
    }

    fn naive(a: &[&[f64]], b: &[&[f64]]) -> DMatrix<f64> {
        DMatrix::from_fn(a.len(), b.len(), |i, j| {
            a[i].iter().zip(b[j]).map(|(x, y)| x * y).sum()
        })
    }

    #[test]
    fn cross_products_match_the_dot_products_over_odd_lengths() {
        for n in [
            0,
            1,
            5,
            BLOCK_ROWS - 1,
            BLOCK_ROWS * CHUNK_BLOCKS + 17,
            3 * BLOCK_ROWS,
        ] {
            let a = columns(9, n);
            let b = columns(4, n);
            let av: Vec<&[f64]> = a.iter().map(Vec::as_slice).collect();
            let bv: Vec<&[f64]> = b.iter().map(Vec::as_slice).collect();
            let want = naive(&av, &bv);
            let got = cross_products(&av, &bv);
            let scale = n.max(1) as f64;
            assert!((got - want).abs().max() < 1e-12 * scale, "n = {n}");
            let g = gram(&av);
            assert!(
                (&g - naive(&av, &av)).abs().max() < 1e-12 * scale,
                "n = {n}"
            );
            assert_eq!(g, g.transpose());
        }
    }

    #[test]
    fn the_sum_is_the_same_whatever_the_thread_count() {
        let a = columns(12, 5 * BLOCK_ROWS * CHUNK_BLOCKS + 3);
        let av: Vec<&[f64]> = a.iter().map(Vec::as_slice).collect();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| gram(&av));
        let four = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap()
            .install(|| gram(&av));
        assert_eq!(one, four);
    }
}

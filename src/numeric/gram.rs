//! Cross products of long columns, `A^T B`, by row blocks.
//!
//! A fit's normal equations need the products of every pair of its basis columns. Taken one
//! pair at a time over the whole record, each product reads two columns from memory: on a long
//! record, whose columns do not fit in the caches, the fit is then bound by memory traffic
//! (m^2 / 2 column reads for m columns) and its time grows faster than the record. Here the
//! record is cut into blocks of [`BLOCK_ROWS`] rows; the block's columns (a few MB together)
//! stay in the caches while every product of the block is taken, so every column is read from
//! memory once per product.
//!
//! Determinism: the blocks are fixed by the record's length alone, grouped into chunks of
//! [`CHUNK_BLOCKS`] summed in order inside a chunk, and the chunks' sums are added in order;
//! each block's products are [`dot`]s with a fixed eight-way split and reduction tree, in plain
//! IEEE arithmetic. So the result is the same bits whatever the thread count and on every
//! machine. (The order differs from a dot product over the whole record: the sums agree to
//! rounding, not bit for bit.)

use nalgebra::DMatrix;
use rayon::prelude::*;
use std::ops::Range;

/// Rows per block: a block of 64 columns is 2 MB (in the caches of current processors).
pub const BLOCK_ROWS: usize = 4096;

/// Blocks summed in order by one task (a task is the unit of parallel work).
pub const CHUNK_BLOCKS: usize = 16;

/// Whether a product over `n` rows keeps every thread of the pool busy by itself (a chunk of
/// blocks per thread at least). Callers that could run several such products side by side (one
/// fit per candidate effect, per output) run them one after the other instead: the same time,
/// a fraction of the memory, and the same bits either way.
pub fn fills_the_threads(n: usize) -> bool {
    n >= BLOCK_ROWS * CHUNK_BLOCKS * rayon::current_num_threads()
}

/// The sum over the record's row blocks of `block(rows)`, each an `r x c` matrix: blocks summed
/// in order within fixed chunks, chunks in parallel, their sums added in order.
pub fn sum_by_row_blocks<F>(n: usize, r: usize, c: usize, block: F) -> DMatrix<f64>
where
    F: Fn(Range<usize>) -> DMatrix<f64> + Sync,
{
    let mut sum = ChunkSum::new(r, c);
    sum.add(chunk_sums(n, r, c, block));
    sum.total()
}

/// Rows per chunk (a task's rows).
pub const CHUNK_ROWS: usize = BLOCK_ROWS * CHUNK_BLOCKS;

/// The chunks' sums of [`sum_by_row_blocks`] over `n` rows, in order (chunks in parallel):
/// added in order to a [`ChunkSum`], the sums of consecutive parts of a record whose starts
/// are multiples of [`CHUNK_ROWS`] give the same bits as the sum over the whole record.
pub fn chunk_sums<F>(n: usize, r: usize, c: usize, block: F) -> Vec<DMatrix<f64>>
where
    F: Fn(Range<usize>) -> DMatrix<f64> + Sync,
{
    let chunks: Vec<Range<usize>> = (0..n.div_ceil(CHUNK_ROWS))
        .map(|k| k * CHUNK_ROWS..((k + 1) * CHUNK_ROWS).min(n))
        .collect();
    chunks
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
        .collect()
}

/// A running sum of chunks' sums ([`chunk_sums`]), added in order.
pub struct ChunkSum(DMatrix<f64>);

impl ChunkSum {
    pub fn new(r: usize, c: usize) -> Self {
        ChunkSum(DMatrix::zeros(r, c))
    }
    /// Add the sums of the next chunks, in order.
    pub fn add(&mut self, sums: Vec<DMatrix<f64>>) {
        for s in sums {
            self.0 = std::mem::replace(&mut self.0, DMatrix::zeros(0, 0)) + s;
        }
    }
    pub fn total(self) -> DMatrix<f64> {
        self.0
    }
}

/// The upper triangle of a Gram matrix mirrored below (exactly symmetric).
pub fn mirror_upper(g: &mut DMatrix<f64>) {
    for i in 0..g.nrows() {
        for j in 0..i {
            g[(i, j)] = g[(j, i)];
        }
    }
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

/// Dot product with eight partial sums in a fixed order (the compiler vectorises it; plain
/// IEEE arithmetic, no fused multiply-add: the same bits on every machine).
#[inline(always)]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..8 {
            acc[i] += x[i] * y[i];
        }
    }
    let mut s = sum8(&acc);
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

/// The eight partial sums of [`dot`] added in its fixed tree (every product of this module
/// ends so: the same bits whichever path took it).
#[inline(always)]
fn sum8(acc: &[f64; 8]) -> f64 {
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]))
}

/// [`dot`] of `a` with each of four columns of `a`'s length, side by side (the same bits as four
/// calls of [`dot`]).
#[inline(always)]
fn dot4(a: &[f64], b: [&[f64]; 4]) -> [f64; 4] {
    let n = a.len();
    let b = b.map(|c| &c[..n]);
    let mut acc = [[0.0f64; 8]; 4];
    let full = n - n % 8;
    for s in (0..full).step_by(8) {
        let x = &a[s..s + 8];
        for (acc, c) in acc.iter_mut().zip(&b) {
            let y = &c[s..s + 8];
            for i in 0..8 {
                acc[i] += x[i] * y[i];
            }
        }
    }
    let mut out = [0.0; 4];
    for ((o, acc), c) in out.iter_mut().zip(&acc).zip(&b) {
        let mut s = sum8(acc);
        for (x, y) in a[full..].iter().zip(&c[full..]) {
            s += x * y;
        }
        *o = s;
    }
    out
}

/// `A^T B` of two blocks with the same rows (column-major: each column contiguous), one dot
/// product per pair of columns on the block (in the caches); only the upper triangle when `b`
/// is `a` itself and `symmetric` is set (the rest left zero).
pub fn tr_mul_block(a: &DMatrix<f64>, b: &DMatrix<f64>, symmetric: bool) -> DMatrix<f64> {
    let rows = a.nrows();
    assert_eq!(b.nrows(), rows, "blocks of different rows");
    tr_mul_slices(&columns_of(a), &columns_of(b), symmetric)
}

/// The columns of a column-major matrix as slices.
fn columns_of(m: &DMatrix<f64>) -> Vec<&[f64]> {
    let rows = m.nrows();
    (0..m.ncols())
        .map(|j| &m.as_slice()[j * rows..(j + 1) * rows])
        .collect()
}

/// [`tr_mul_block`] of the columns' slices on a block of rows (each slice contiguous and in the
/// caches, so nothing is copied): the same bits.
pub fn tr_mul_slices(a: &[&[f64]], b: &[&[f64]], symmetric: bool) -> DMatrix<f64> {
    let (k, c) = (a.len(), b.len());
    let rows = a.first().or(b.first()).map_or(0, |x| x.len());
    let mut out = DMatrix::zeros(k, c);
    if rows == 0 {
        return out;
    }
    assert!(
        a.iter().chain(b).all(|x| x.len() == rows),
        "blocks of different rows"
    );
    // the columns of each row of `out` that tiles of 4 x 4 products gave (AVX-512), the rest
    // one product or four at a time
    let from = tiles_4x4(a, b, symmetric, &mut out);
    crate::numeric::simd::wide(
        #[inline(always)]
        || {
            for i in 0..k {
                let ai = a[i];
                let mut j = from[i];
                // four columns of `b` against one of `a`: the column of `a` is loaded once for four
                // products (each product's arithmetic is that of `dot`)
                while j + 4 <= c {
                    let d = dot4(ai, [b[j], b[j + 1], b[j + 2], b[j + 3]]);
                    for (l, v) in d.into_iter().enumerate() {
                        out[(i, j + l)] = v;
                    }
                    j += 4;
                }
                for j in j..c {
                    out[(i, j)] = dot(ai, b[j]);
                }
            }
        },
    );
    out
}

/// The products of [`tr_mul_slices`] that come in whole tiles of four columns of `a` against
/// four of `b` (rows of `a` in fours from the first, columns of `b` in fours from the row's
/// first wanted column), taken with AVX-512 where the processor has it: sixteen products side
/// by side, each with its eight partial sums in one register, so that every column is loaded
/// once for four products (2.6x the four-at-a-time products of [`dot4`] on 56 columns of 4096
/// rows). Each product is [`dot`]'s arithmetic: the same bits. Returns, per row of `a`, the
/// first column left to the caller (its first wanted column when no tile was taken).
fn tiles_4x4(a: &[&[f64]], b: &[&[f64]], symmetric: bool, out: &mut DMatrix<f64>) -> Vec<usize> {
    let (k, c) = (a.len(), b.len());
    let start = |i: usize| if symmetric { i.min(c) } else { 0 };
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
    let mut from: Vec<usize> = (0..k).map(start).collect();
    #[cfg(target_arch = "x86_64")]
    if crate::numeric::simd::uses_avx512() {
        for i0 in (0..k - k % 4).step_by(4) {
            let j0 = start(i0);
            let j_end = j0 + (c - j0) / 4 * 4;
            for j in (j0..j_end).step_by(4) {
                // SAFETY: the processor supports AVX-512F (checked above); the columns have
                // one length (checked by the caller).
                let d = unsafe { products_4x4(four(a, i0), four(b, j)) };
                for (u, row) in d.iter().enumerate() {
                    for (v, x) in row.iter().enumerate() {
                        if !symmetric || j + v >= i0 + u {
                            out[(i0 + u, j + v)] = *x;
                        }
                    }
                }
            }
            for (u, f) in from[i0..i0 + 4].iter_mut().enumerate() {
                *f = j_end.max(start(i0 + u));
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (a, b, out);
    from
}

/// The four columns of `x` from `s`.
#[cfg(target_arch = "x86_64")]
fn four<'x>(x: &[&'x [f64]], s: usize) -> [&'x [f64]; 4] {
    [x[s], x[s + 1], x[s + 2], x[s + 3]]
}

/// The sixteen products of four columns `a` with four columns `b` (one length), each with
/// [`dot`]'s eight partial sums (lane `l` of a register holds partial sum `l`), reduction tree
/// and tail.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn products_4x4(a: [&[f64]; 4], b: [&[f64]; 4]) -> [[f64; 4]; 4] {
    use std::arch::x86_64::{__m512d, _mm512_storeu_pd};
    use std::arch::x86_64::{_mm512_add_pd, _mm512_loadu_pd, _mm512_mul_pd, _mm512_setzero_pd};
    let n = a[0].len();
    assert!(a.iter().chain(&b).all(|x| x.len() == n));
    let full = n - n % 8;
    let mut acc: [[__m512d; 4]; 4] = [[_mm512_setzero_pd(); 4]; 4];
    for s in (0..full).step_by(8) {
        // SAFETY: s + 8 <= full <= n, the columns' length
        let x = a.map(|c| unsafe { _mm512_loadu_pd(c.as_ptr().add(s)) });
        for (v, col) in b.iter().enumerate() {
            let y = unsafe { _mm512_loadu_pd(col.as_ptr().add(s)) };
            for (u, xu) in x.iter().enumerate() {
                acc[u][v] = _mm512_add_pd(acc[u][v], _mm512_mul_pd(*xu, y));
            }
        }
    }
    let mut out = [[0.0; 4]; 4];
    for (u, row) in out.iter_mut().enumerate() {
        for (v, o) in row.iter_mut().enumerate() {
            let mut p = [0.0f64; 8];
            // SAFETY: `p` holds eight doubles
            unsafe { _mm512_storeu_pd(p.as_mut_ptr(), acc[u][v]) };
            let mut s = sum8(&p);
            for (x, y) in a[u][full..].iter().zip(&b[v][full..]) {
                s += x * y;
            }
            *o = s;
        }
    }
    out
}

/// `A^T B` for columns `a` and `b` of one length `n` (`a.len() x b.len()`).
pub fn cross_products(a: &[&[f64]], b: &[&[f64]]) -> DMatrix<f64> {
    let n = a.first().or(b.first()).map_or(0, |c| c.len());
    debug_assert!(a.iter().chain(b).all(|c| c.len() == n));
    sum_by_row_blocks(n, a.len(), b.len(), |rows| {
        let a: Vec<&[f64]> = a.iter().map(|x| &x[rows.clone()]).collect();
        let b: Vec<&[f64]> = b.iter().map(|x| &x[rows.clone()]).collect();
        tr_mul_slices(&a, &b, false)
    })
}

/// `A^T A` for columns `a` of one length: the upper triangle computed, mirrored (exactly
/// symmetric).
pub fn gram(a: &[&[f64]]) -> DMatrix<f64> {
    let n = a.first().map_or(0, |c| c.len());
    debug_assert!(a.iter().all(|c| c.len() == n));
    let k = a.len();
    let mut g = sum_by_row_blocks(n, k, k, |rows| {
        let x: Vec<&[f64]> = a.iter().map(|c| &c[rows.clone()]).collect();
        tr_mul_slices(&x, &x, true)
    });
    mirror_upper(&mut g);
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
    fn every_product_of_a_block_is_its_dot_product_bit_for_bit() {
        // tiles of 4 x 4 (AVX-512 where the processor has it), fours and ones at the edges:
        // every entry is `dot` of its two columns, whichever path took it
        for (k, c, n) in [
            (9, 11, 8 * 40 + 5),
            (4, 4, 8),
            (13, 6, 3),
            (7, 17, 64),
            (3, 2, 9),
        ] {
            let a = columns(k, n);
            let b: Vec<Vec<f64>> = columns(c + 2, n).split_off(2);
            let av: Vec<&[f64]> = a.iter().map(Vec::as_slice).collect();
            let bv: Vec<&[f64]> = b.iter().map(Vec::as_slice).collect();
            let got = tr_mul_slices(&av, &bv, false);
            for i in 0..k {
                for j in 0..c {
                    let want = dot(av[i], bv[j]);
                    assert_eq!(got[(i, j)].to_bits(), want.to_bits(), "{k}x{c}, ({i}, {j})");
                }
            }
            let sym = tr_mul_slices(&av, &av, true);
            for i in 0..k {
                for j in 0..k {
                    let want = if j >= i { dot(av[i], av[j]) } else { 0.0 };
                    assert_eq!(sym[(i, j)].to_bits(), want.to_bits(), "{k} sym, ({i}, {j})");
                }
            }
        }
        if !crate::numeric::simd::uses_avx512() {
            eprintln!("note: no AVX-512 here, the tiles' path was not taken");
        }
    }

    #[test]
    fn four_products_side_by_side_are_four_dot_products() {
        let c = columns(5, 8 * 9 + 5);
        let d = dot4(&c[0], [&c[1], &c[2], &c[3], &c[4]]);
        for l in 0..4 {
            assert_eq!(d[l].to_bits(), dot(&c[0], &c[l + 1]).to_bits());
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

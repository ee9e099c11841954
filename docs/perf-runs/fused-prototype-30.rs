// Twenty-fourth round (docs/performance.md, "On the AMD EPYC Zen 4 host the issue names"):
// a stand-alone prototype, not part of the build. The peer scene's springs and symplectic
// Euler on an n x n grid, no contacts, three ways: "two" (the band kernel's structure: every
// class's forces of a row into ring rows, then the integration reading 12 terms), "fused"
// (all six classes per chunk from shared loads, forces still through rows) and "fused2" (all
// six classes per chunk, the row's own terms kept in registers and integrated at once, only
// the terms later rows read stored). All three give the same bits (printed).
// Run: a Cargo package with this as src/main.rs, `cargo run --release -- 128 2000`.
// Prototype: two-phase (springs to ring rows, then integrate) vs fused (all classes per chunk,
// shared loads, only later-row terms stored) on the peer scene's grid, no contacts.
use std::time::Instant;
const L: usize = 16;
const PAD: usize = 16; // front/back padding of rows (floats)
// classes: (dr, a_dc, b_dc)
const CL: [(usize, usize, usize); 6] = [(1, 0, 0), (0, 0, 1), (1, 0, 1), (1, 1, 0), (2, 0, 0), (0, 0, 2)];
const WARP: usize = 0; const WEFT: usize = 1; const DIAG: usize = 2; const ANTI: usize = 3; const BV: usize = 4; const BH: usize = 5;

struct S { rows: usize, cols: usize, w: usize, x: [Vec<f32>; 6] } // padded rows: index r*w + PAD + c
impl S {
    fn new(n: usize) -> S {
        let w = n + 2 * PAD;
        let mut x: [Vec<f32>; 6] = std::array::from_fn(|_| vec![0.0; (n + 3) * w]);
        let q = 1.0 / n as f32;
        for r in 0..n { for c in 0..n {
            let i = r * w + PAD + c;
            x[0][i] = c as f32 * q - 0.5 + 0.0003 * ((r * 7 + c * 3) % 11) as f32;
            x[1][i] = 0.6 + 0.0002 * ((r * 5 + c) % 7) as f32;
            x[2][i] = r as f32 * q - 0.5;
        }}
        S { rows: n, cols: n, w, x }
    }
}
struct P { k: [f32; 6], c: [f32; 6], rest: [f32; 6], h: f32, g: f32, d: f32 }

#[inline(always)]
fn spring(a: [&[f32; L]; 6], b: [&[f32; L]; 6], j: usize, k: f32, c: f32, rest: f32) -> [f32; 3] {
    let lx = b[0][j] - a[0][j]; let ly = b[1][j] - a[1][j]; let lz = b[2][j] - a[2][j];
    let len = (lx * lx + ly * ly + lz * lz).sqrt();
    let inv = 1.0 / len;
    let (dx, dy, dz) = (lx * inv, ly * inv, lz * inv);
    let (wx, wy, wz) = (b[3][j] - a[3][j], b[4][j] - a[4][j], b[5][j] - a[5][j]);
    let m = k * (len - rest) + c * (wx * dx + wy * dy + wz * dz);
    [m * dx, m * dy, m * dz]
}

fn row<'a>(x: &'a [Vec<f32>; 6], w: usize, r: usize, off: usize) -> [&'a [f32]; 6] {
    std::array::from_fn(|k| &x[k][r * w + off..])
}

// Two-phase: per row, each class's springs into ring[class][slot][comp] (padded), then the integration.
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,fma,avx2")]
fn step_two_phase(s: &S, p: &P, out: &mut [Vec<f32>; 6], ring: &mut Vec<f32>) {
    let (rows, cols, w) = (s.rows, s.cols, s.w);
    let rl = w; // ring row length
    let idx = |class: usize, slot: usize, comp: usize| ((class * 3 + slot) * 3 + comp) * rl;
    for r in 0..rows {
        for class in 0..6 {
            let (dr, adc, bdc) = CL[class];
            let slot = r % 3;
            if r + dr >= rows { continue; }
            let a = row(&s.x, w, r, PAD + adc); let b = row(&s.x, w, r + dr, PAD + bdc);
            let m = cols - adc.max(bdc);
            let (fx, rest) = ring.split_at_mut(idx(class, slot, 1));
            let fx = &mut fx[idx(class, slot, 0) + PAD..][..cols];
            let (fy, fz) = rest.split_at_mut(rl);
            let (fy, fz) = (&mut fy[PAD..][..cols], &mut fz[PAD..][..cols]);
            let mut c0 = 0;
            while c0 < cols {
                let a = ch(a, c0);
                let b = ch(b, c0);
                let (ox, oy, oz) = (lnm(fx, c0), lnm(fy, c0), lnm(fz, c0));
                for j in 0..L { let f = spring(a, b, j, p.k[class], p.c[class], p.rest[class]); ox[j] = f[0]; oy[j] = f[1]; oz[j] = f[2]; }
                c0 += L;
            }
            let back = if class == ANTI { 0.0 } else { -0.0 };
            for comp in 0..3 { let base = idx(class, slot, comp) + PAD; for v in &mut ring[base + m..base + cols] { *v = back; } }
        }
        // integrate row r
        for comp in 0..3 {
            let t = |class: usize, rr: Option<usize>, off: isize| -> &[f32] {
                match rr { Some(rr) if rr + CL[class].0 < rows => &ring[(idx(class, rr % 3, comp) as isize + PAD as isize + off) as usize..], _ => &ZERO[..] }
            };
            let up1 = r.checked_sub(1); let up2 = r.checked_sub(2);
            let ts = [t(WARP, up1, 0), t(WARP, Some(r), 0), t(WEFT, Some(r), -1), t(WEFT, Some(r), 0), t(DIAG, up1, -1), t(ANTI, up1, 0), t(ANTI, Some(r), -1), t(DIAG, Some(r), 0), t(BV, up2, 0), t(BH, Some(r), -2), t(BV, Some(r), 0), t(BH, Some(r), 0)];
            let xo = &s.x[comp][r * w + PAD..]; let vo = &s.x[3 + comp][r * w + PAD..];
            let (ox, ov) = out.split_at_mut(3);
            let ox = &mut ox[comp][r * w + PAD..][..cols]; let ov = &mut ov[comp][r * w + PAD..][..cols];
            let g = if comp == 1 { p.g } else { 0.0 };
            let mut c0 = 0;
            while c0 < cols {
                let tl: [&[f32; L]; 12] = [ln(ts[0], c0), ln(ts[1], c0), ln(ts[2], c0), ln(ts[3], c0), ln(ts[4], c0), ln(ts[5], c0), ln(ts[6], c0), ln(ts[7], c0), ln(ts[8], c0), ln(ts[9], c0), ln(ts[10], c0), ln(ts[11], c0)];
                let (x, v) = (ln(xo, c0), ln(vo, c0));
                let (oxl, ovl) = (lnm(ox, c0), lnm(ov, c0));
                for j in 0..L {
                    let mut f = 1.0 * g - p.d * v[j];
                    f -= tl[0][j]; f += tl[1][j]; f -= tl[2][j]; f += tl[3][j]; f -= tl[4][j]; f -= tl[5][j];
                    f += tl[6][j]; f += tl[7][j]; f -= tl[8][j]; f -= tl[9][j]; f += tl[10][j]; f += tl[11][j];
                    let nv = v[j] + p.h * f; ovl[j] = nv; oxl[j] = x[j] + p.h * nv;
                }
                c0 += L;
            }
        }
    }
}
#[inline(always)]
fn ch<'a>(a: [&'a [f32]; 6], c0: usize) -> [&'a [f32; L]; 6] { [ln(a[0], c0), ln(a[1], c0), ln(a[2], c0), ln(a[3], c0), ln(a[4], c0), ln(a[5], c0)] }
#[inline(always)]
fn ln(a: &[f32], c0: usize) -> &[f32; L] { a[c0..c0 + L].try_into().unwrap() }
#[inline(always)]
fn lnm(a: &mut [f32], c0: usize) -> &mut [f32; L] { (&mut a[c0..c0 + L]).try_into().unwrap() }
static ZERO: [f32; 4096] = [0.0; 4096];

// Fused: per row, per chunk: all six classes from shared loads, the row's own terms kept
// (shifted ones from the previous chunk's values), later-row terms stored in a ring.
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,fma,avx2")]
fn step_fused(s: &S, p: &P, out: &mut [Vec<f32>; 6], ring: &mut Vec<f32>, own: &mut Vec<f32>) {
    let (rows, cols, w) = (s.rows, s.cols, s.w);
    let rl = w;
    // ring: classes warp, diag, anti, bendv (4) x 3 slots x 3 comps
    let idx = |ci: usize, slot: usize, comp: usize| ((ci * 3 + slot) * 3 + comp) * rl;
    // own: this row's weft, anti, bendh forces (for the shifted terms): 3 classes x 3 comps, padded
    let oidx = |ci: usize, comp: usize| (ci * 3 + comp) * rl;
    for v in own.iter_mut() { *v = 0.0; }
    for r in 0..rows {
        let slot = r % 3;
        let has = |dr: usize| r + dr < rows;
        let r0 = row(&s.x, w, r, PAD); let r1 = row(&s.x, w, r, PAD + 1); let r2 = row(&s.x, w, r, PAD + 2);
        let n0 = row(&s.x, w, (r + 1).min(rows), PAD); let n1 = row(&s.x, w, (r + 1).min(rows), PAD + 1);
        let m0 = row(&s.x, w, (r + 2).min(rows + 1), PAD);
        let up1 = r.checked_sub(1); let up2 = r.checked_sub(2);
        let mut c0 = 0;
        while c0 < cols {
            let (a0, a1, a2, b0, b1, c2) = (ch(r0, c0), ch(r1, c0), ch(r2, c0), ch(n0, c0), ch(n1, c0), ch(m0, c0));
            let mut fw = [[0.0f32; L]; 3]; let mut fwe = [[0.0f32; L]; 3]; let mut fd = [[0.0f32; L]; 3];
            let mut fa = [[0.0f32; L]; 3]; let mut fbv = [[0.0f32; L]; 3]; let mut fbh = [[0.0f32; L]; 3];
            for j in 0..L {
                let f = spring(a0, b0, j, p.k[WARP], p.c[WARP], p.rest[WARP]); for k in 0..3 { fw[k][j] = f[k]; }
                let f = spring(a0, a1, j, p.k[WEFT], p.c[WEFT], p.rest[WEFT]); for k in 0..3 { fwe[k][j] = f[k]; }
                let f = spring(a0, b1, j, p.k[DIAG], p.c[DIAG], p.rest[DIAG]); for k in 0..3 { fd[k][j] = f[k]; }
                let f = spring(a1, b0, j, p.k[ANTI], p.c[ANTI], p.rest[ANTI]); for k in 0..3 { fa[k][j] = f[k]; }
                let f = spring(a0, c2, j, p.k[BV], p.c[BV], p.rest[BV]); for k in 0..3 { fbv[k][j] = f[k]; }
                let f = spring(a0, a2, j, p.k[BH], p.c[BH], p.rest[BH]); for k in 0..3 { fbh[k][j] = f[k]; }
            }
            // masks of existing springs (padding values) — simplified: columns past the row's springs
            for j in 0..L {
                let c = c0 + j;
                if c + 1 >= cols { for k in 0..3 { fwe[k][j] = -0.0; fd[k][j] = -0.0; fa[k][j] = 0.0; } }
                if c + 2 >= cols { for k in 0..3 { fbh[k][j] = -0.0; } }
                if !has(1) { for k in 0..3 { fw[k][j] = -0.0; fd[k][j] = -0.0; fa[k][j] = 0.0; } }
                if !has(2) { for k in 0..3 { fbv[k][j] = -0.0; } }
            }
            for comp in 0..3 {
                // store later-row terms and own shifted terms
                let store = |ring: &mut Vec<f32>, base: usize, v: &[f32; L]| ring[base + PAD + c0..][..L].copy_from_slice(v);
                store(ring, idx(0, slot, comp), &fw[comp]); store(ring, idx(1, slot, comp), &fd[comp]);
                store(ring, idx(2, slot, comp), &fa[comp]); store(ring, idx(3, slot, comp), &fbv[comp]);
                store(own, oidx(0, comp), &fwe[comp]); store(own, oidx(1, comp), &fa[comp]); store(own, oidx(2, comp), &fbh[comp]);
            }
            c0 += L;
        }
        // integrate row r (a second loop over the row: the shifted own terms from `own`)
        for comp in 0..3 {
            let rt = |ci: usize, rr: Option<usize>, dr: usize, off: isize| -> &[f32] {
                match rr { Some(rr) if rr + dr < rows => &ring[(idx(ci, rr % 3, comp) as isize + PAD as isize + off) as usize..], _ => &ZERO[..] }
            };
            let ot = |ci: usize, off: isize| -> &[f32] { &own[(oidx(ci, comp) as isize + PAD as isize + off) as usize..] };
            let ts = [rt(0, up1, 1, 0), rt(0, Some(r), 1, 0), ot(0, -1), ot(0, 0), rt(1, up1, 1, -1), rt(2, up1, 1, 0), ot(1, -1), rt(1, Some(r), 1, 0), rt(3, up2, 2, 0), ot(2, -2), rt(3, Some(r), 2, 0), ot(2, 0)];
            let xo = &s.x[comp][r * w + PAD..]; let vo = &s.x[3 + comp][r * w + PAD..];
            let (ox, ov) = out.split_at_mut(3);
            let ox = &mut ox[comp][r * w + PAD..][..cols]; let ov = &mut ov[comp][r * w + PAD..][..cols];
            let g = if comp == 1 { p.g } else { 0.0 };
            let mut c0 = 0;
            while c0 < cols {
                let tl: [&[f32; L]; 12] = [ln(ts[0], c0), ln(ts[1], c0), ln(ts[2], c0), ln(ts[3], c0), ln(ts[4], c0), ln(ts[5], c0), ln(ts[6], c0), ln(ts[7], c0), ln(ts[8], c0), ln(ts[9], c0), ln(ts[10], c0), ln(ts[11], c0)];
                let (x, v) = (ln(xo, c0), ln(vo, c0));
                let (oxl, ovl) = (lnm(ox, c0), lnm(ov, c0));
                for j in 0..L {
                    let mut f = 1.0 * g - p.d * v[j];
                    f -= tl[0][j]; f += tl[1][j]; f -= tl[2][j]; f += tl[3][j]; f -= tl[4][j]; f -= tl[5][j];
                    f += tl[6][j]; f += tl[7][j]; f -= tl[8][j]; f -= tl[9][j]; f += tl[10][j]; f += tl[11][j];
                    let nv = v[j] + p.h * f; ovl[j] = nv; oxl[j] = x[j] + p.h * nv;
                }
                c0 += L;
            }
        }
    }
}


#[inline(always)]
fn shift<const K: usize>(prev: &[f32; L], cur: &[f32; L]) -> [f32; L] {
    std::array::from_fn(|j| if j < K { prev[L - K + j] } else { cur[j - K] })
}

// Fused with the row's own terms in registers: springs, then the integration of the chunk.
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,fma,avx2")]
fn step_fused2(s: &S, p: &P, out: &mut [Vec<f32>; 6], ring: &mut Vec<f32>) {
    let (rows, cols, w) = (s.rows, s.cols, s.w);
    let rl = w;
    let idx = |ci: usize, slot: usize, comp: usize| ((ci * 3 + slot) * 3 + comp) * rl;
    for r in 0..rows {
        let slot = r % 3;
        let has = |dr: usize| r + dr < rows;
        let r0 = row(&s.x, w, r, PAD); let r1 = row(&s.x, w, r, PAD + 1); let r2 = row(&s.x, w, r, PAD + 2);
        let n0 = row(&s.x, w, (r + 1).min(rows), PAD); let n1 = row(&s.x, w, (r + 1).min(rows), PAD + 1);
        let m0 = row(&s.x, w, (r + 2).min(rows + 1), PAD);
        let up1 = r.checked_sub(1); let up2 = r.checked_sub(2);
        let mut prev_we = [[0.0f32; L]; 3]; let mut prev_a = [[-0.0f32; L]; 3]; let mut prev_bh = [[0.0f32; L]; 3];
        let mut c0 = 0;
        while c0 < cols {
            let (a0, a1, a2, b0, b1, c2) = (ch(r0, c0), ch(r1, c0), ch(r2, c0), ch(n0, c0), ch(n1, c0), ch(m0, c0));
            let mut fw = [[0.0f32; L]; 3]; let mut fwe = [[0.0f32; L]; 3]; let mut fd = [[0.0f32; L]; 3];
            let mut fa = [[0.0f32; L]; 3]; let mut fbv = [[0.0f32; L]; 3]; let mut fbh = [[0.0f32; L]; 3];
            for j in 0..L {
                let f = spring(a0, b0, j, p.k[WARP], p.c[WARP], p.rest[WARP]); for k in 0..3 { fw[k][j] = f[k]; }
                let f = spring(a0, a1, j, p.k[WEFT], p.c[WEFT], p.rest[WEFT]); for k in 0..3 { fwe[k][j] = f[k]; }
                let f = spring(a0, b1, j, p.k[DIAG], p.c[DIAG], p.rest[DIAG]); for k in 0..3 { fd[k][j] = f[k]; }
                let f = spring(a1, b0, j, p.k[ANTI], p.c[ANTI], p.rest[ANTI]); for k in 0..3 { fa[k][j] = f[k]; }
                let f = spring(a0, c2, j, p.k[BV], p.c[BV], p.rest[BV]); for k in 0..3 { fbv[k][j] = f[k]; }
                let f = spring(a0, a2, j, p.k[BH], p.c[BH], p.rest[BH]); for k in 0..3 { fbh[k][j] = f[k]; }
            }
            if c0 + L >= cols || !has(2) {
                for j in 0..L {
                    let c = c0 + j;
                    if c + 1 >= cols { for k in 0..3 { fwe[k][j] = -0.0; fd[k][j] = -0.0; fa[k][j] = 0.0; } }
                    if c + 2 >= cols { for k in 0..3 { fbh[k][j] = -0.0; } }
                    if !has(1) { for k in 0..3 { fw[k][j] = -0.0; fd[k][j] = -0.0; fa[k][j] = 0.0; } }
                    if !has(2) { for k in 0..3 { fbv[k][j] = -0.0; } }
                }
            }
            for comp in 0..3 {
                let rt = |ci: usize, rr: Option<usize>, dr: usize, off: isize| -> &[f32; L] {
                    match rr { Some(rr) if rr + dr < rows => ln(&ring[(idx(ci, rr % 3, comp) as isize + PAD as isize + off) as usize..], c0), _ => ln(&ZERO[..], 0) }
                };
                let t0 = *rt(0, up1, 1, 0); let t4 = *rt(1, up1, 1, -1); let t5 = *rt(2, up1, 1, 0); let t8 = *rt(3, up2, 2, 0);
                let t2 = shift::<1>(&prev_we[comp], &fwe[comp]);
                let t6 = shift::<1>(&prev_a[comp], &fa[comp]);
                let t9 = shift::<2>(&prev_bh[comp], &fbh[comp]);
                let xo = ln(&s.x[comp][r * w + PAD..], c0); let vo = ln(&s.x[3 + comp][r * w + PAD..], c0);
                let (ox, ov) = out.split_at_mut(3);
                let oxl = lnm(&mut ox[comp][r * w + PAD..], c0); let ovl = lnm(&mut ov[comp][r * w + PAD..], c0);
                let g = if comp == 1 { p.g } else { 0.0 };
                for j in 0..L {
                    let mut f = 1.0 * g - p.d * vo[j];
                    f -= t0[j]; f += fw[comp][j]; f -= t2[j]; f += fwe[comp][j]; f -= t4[j]; f -= t5[j];
                    f += t6[j]; f += fd[comp][j]; f -= t8[j]; f -= t9[j]; f += fbv[comp][j]; f += fbh[comp][j];
                    let nv = vo[j] + p.h * f; ovl[j] = nv; oxl[j] = xo[j] + p.h * nv;
                }
            }
            for comp in 0..3 {
                let store = |ring: &mut Vec<f32>, base: usize, v: &[f32; L]| ring[base + PAD + c0..][..L].copy_from_slice(v);
                store(ring, idx(0, slot, comp), &fw[comp]); store(ring, idx(1, slot, comp), &fd[comp]);
                store(ring, idx(2, slot, comp), &fa[comp]); store(ring, idx(3, slot, comp), &fbv[comp]);
            }
            prev_we = fwe; prev_a = fa; prev_bh = fbh;
            c0 += L;
        }
    }
}

fn main() {
    let n: usize = std::env::args().nth(1).map_or(128, |s| s.parse().unwrap());
    let steps: usize = std::env::args().nth(2).map_or(2000, |s| s.parse().unwrap());
    let q = 1.0 / n as f32;
    let rest = [q, q, q * 2f32.sqrt(), q * 2f32.sqrt(), 2.0 * q, 2.0 * q];
    let p = P { k: rest.map(|l| 3e4 / l), c: [1e4 * q; 6], rest, h: 0.04 / n as f32, g: -9.8, d: 0.0 };
    for mode in ["two", "fused", "fused2", "two", "fused", "fused2", "two", "fused", "fused2"] {
        let mut s = S::new(n);
        let mut out = s.x.clone();
        let mut ring = vec![0.0f32; 6 * 9 * s.w];
        let mut own = vec![0.0f32; 9 * s.w];
        let t = Instant::now();
        for _ in 0..steps {
            unsafe { match mode { "two" => step_two_phase(&s, &p, &mut out, &mut ring), "fused" => step_fused(&s, &p, &mut out, &mut ring, &mut own), _ => step_fused2(&s, &p, &mut out, &mut ring) } }
            std::mem::swap(&mut s.x, &mut out);
        }
        let el = t.elapsed().as_secs_f64();
        let sum: f64 = s.x[1].iter().map(|&v| v as f64).sum();
        let bits: u64 = s.x.iter().flatten().fold(0u64, |h, v| h.wrapping_mul(31).wrapping_add(v.to_bits() as u64));
        println!("{mode:6} {:.3e} particle-substeps/s  checksum {sum:.6} bits {bits:x}", (n * n * steps) as f64 / el);
    }
}

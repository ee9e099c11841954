// The timing experiment of the fiftieth round (docs/performance.md): appended to crates/cloth-core/src/solver/chains.rs as an ignored test and run with
// cargo test --release -p cloth-core --lib chain_step_cost -- --ignored --nocapture (PAD=n: the scratch n floats further on; the PAIR switch of the round's first form, two blocks per call, has no effect since the solve takes one block).
// It prints the best of 7 timings of one block's solve per chain step; not a test of the crate (timings are not tests).

#[cfg(test)]
mod microbench {
    use super::*;
    #[test]
    #[ignore = "timing experiment"]
    fn chain_step_cost() {
        let kernel = crate::simd::Kernel::best();
        let pair = std::env::var_os("PAIR").is_some();
        for len in [16usize, 64, 256, 512] {
            let size = stride(len);
            let mut fields = vec![0.0_f32; FIELDS * size * 2];
            let mut work = vec![0.0_f32; 2 * SCRATCH * size];
            for b in 0..2 {
                let f = &mut fields[b * FIELDS * size..][..FIELDS * size];
                for k in 0..len {
                    for l in 0..LANES {
                        let e = k * LANES + l;
                        let t = k as f32;
                        f[e] = 0.011 * t + 0.001 * l as f32;
                        f[size + e] = 0.002 * (t * 1.3).sin();
                        f[2 * size + e] = 0.0015 * (t * 0.7).cos();
                        f[3 * size + e] = f[e] - 0.0001;
                        f[4 * size + e] = f[size + e];
                        f[5 * size + e] = f[2 * size + e];
                        f[6 * size + e] = 2.0;
                        f[7 * size + e] = 0.01;
                    }
                }
            }
            let reps = 1000 * 512 / len;
            let mut best = f64::MAX;
            for _ in 0..7 {
                let t0 = std::time::Instant::now();
                for _ in 0..reps {
                    let (f1, f2) = fields.split_at_mut(FIELDS * size);
                    let (w1, w2) = work.split_at_mut(SCRATCH * size);
                    let b1 = Block::split(f1, w1, size);
                    let b2 = Block::split(f2, w2, size);
                    let _ = pair;
                    crate::simd::xpbd_chains(kernel, b1, len, 1e-3, 0.05, true, None);
                    crate::simd::xpbd_chains(kernel, b2, len, 1e-3, 0.05, true, None);
                }
                let ns = t0.elapsed().as_secs_f64() * 1e9 / (reps * 2 * len) as f64;
                best = best.min(ns);
            }
            println!("len {len:4} pair {pair}: {best:.2} ns per block-step ({kernel:?})");
        }
    }
}

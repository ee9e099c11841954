use cloth_core::{SpringClass, presets};
use std::time::Instant;
fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let p = |i: usize| -> u32 { a[i].parse().unwrap() };
    let (n, s1, r1, f1, s2, r2, frames) = (p(0) as usize, p(1), p(2), p(3), p(4), p(5), p(6));
    let threads: usize = a.get(7).map(|s| s.parse().unwrap()).unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let mut sim = presets::realtime_drape(n, s1, r1).unwrap();
        let mut ms = Vec::new();
        let mut late_max = 0f32; let mut late_at = 0; let mut after_max = 0f32;
        for f in 0..frames {
            if f == f1 { let mut c = *sim.config(); c.substeps = s2; c.xpbd.chain_rounds = r2; sim.set_config(c).unwrap(); }
            let t = Instant::now();
            let s = sim.step().unwrap();
            ms.push(t.elapsed().as_secs_f64() * 1e3);
            let st = s.strain(SpringClass::Structural);
            if f >= frames / 2 && st > late_max { late_max = st; late_at = f; }
            if f >= f1 { after_max = after_max.max(st); }
        }
        let med = |v: &[f64]| { let mut s = v.to_vec(); s.sort_by(|a, b| a.partial_cmp(b).unwrap()); s[s.len() / 2] };
        let thirds: Vec<String> = ms.chunks(ms.len() / 6).map(|c| format!("{:.1}", med(c))).collect();
        eprintln!("medians by sixth: {}", thirds.join(" "));
        println!("n={n} {s1}x{r1}x2 until frame {f1}, then {s2}x{r2}x2, {frames} frames: median {:.2} ms, before switch {:.2}, after {:.2}; late_max {:.2}% at frame {late_at}, max after switch {:.2}%",
            med(&ms), med(&ms[..f1 as usize]), med(&ms[f1 as usize..]), late_max * 100.0, after_max * 100.0);
    });
}

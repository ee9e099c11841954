use cloth_core::{SpringClass, presets};
use std::time::Instant;
fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let n: usize = a[0].parse().unwrap();
    let s1: u32 = a[1].parse().unwrap();
    let f1: u32 = a[2].parse().unwrap();
    let s2: u32 = a[3].parse().unwrap();
    let frames: u32 = a[4].parse().unwrap();
    let threads: usize = a.get(5).map(|s| s.parse().unwrap()).unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut sim = presets::realtime_drape(n, s1).unwrap();
        let mut ms = Vec::new();
        let mut late_max = 0f32; let mut late_at = 0; let mut late_shear = 0f32;
        for f in 0..frames {
            if f == f1 { let mut c = *sim.config(); c.substeps = s2; sim.set_config(c).unwrap(); }
            let t = Instant::now();
            let s = sim.step().unwrap();
            ms.push(t.elapsed().as_secs_f64() * 1e3);
            let st = s.strain(SpringClass::Structural);
            if f >= frames / 2 && st > late_max { late_max = st; late_at = f; }
            if f >= frames / 2 { late_shear = late_shear.max(s.strain(SpringClass::Shear)); }
            if f % 10 == 9 { eprintln!("frame {f} strain {:.2}% ms {:.1}", st * 100.0, ms[ms.len()-1]); }
        }
        let mut sorted = ms.clone(); sorted.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let late: Vec<f64> = ms[f1 as usize..].to_vec();
        let mut ls = late.clone(); ls.sort_by(|a, b| a.partial_cmp(b).unwrap());
        println!("n={n} s1={s1} f1={f1} s2={s2} frames={frames}: median {:.2} ms, median after switch {:.2} ms, max {:.1}; late_max {:.2}% at frame {late_at}, late_shear {:.1}%",
            sorted[sorted.len()/2], ls[ls.len()/2], sorted[sorted.len()-1], late_max*100.0, late_shear*100.0);
    });
}

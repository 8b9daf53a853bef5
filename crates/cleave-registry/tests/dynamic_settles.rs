//! A dynamic run that settles must land on the static answer of the same mesh: the dynamic beam
//! of benchmarks.md §3 for every variant of every registered backend, against the same method's
//! static cantilever deflection on the same mesh scaled by the Young's moduli.

use cleave_registry::registered;
use cleave_testkit::compare::{Problem, run_problem, self_consistency};

#[test]
fn every_dynamic_beam_comes_to_rest_on_its_own_static_deflection() {
    let mut worst: f64 = 0.0;
    let all = registered();
    let runs = all.iter().flat_map(|b| b.variants().into_iter().map(move |v| (b, v)));
    for (b, variant) in runs {
        let (name, variant) = (b.name(), variant.as_str());
        let n = 2;
        let statics = run_problem(b.as_ref(), variant, Problem::Cantilever, n).expect("static solve");
        let dynamic = run_problem(b.as_ref(), variant, Problem::Dynamic, n).expect("dynamic run");
        let rows = [statics.clone(), dynamic.clone()];
        let mismatch = self_consistency(&dynamic, &rows).expect("both rows have a tip");
        println!(
            "{name}/{variant} n = {n}: dynamic tip {:.6e} m, static {:.6e} m × 1e-2, mismatch {:+.4} %",
            dynamic.tip_uz_avg.unwrap(),
            statics.tip_uz_avg.unwrap(),
            100.0 * mismatch
        );
        worst = worst.max(mismatch.abs());
        assert!(
            mismatch.abs() < 0.01,
            "{name}/{variant}: the settled tip is {:.2} % off its static answer",
            100.0 * mismatch
        );
    }
    println!("largest mismatch {:.4} %", 100.0 * worst);
}

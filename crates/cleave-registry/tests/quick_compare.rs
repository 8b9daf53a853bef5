//! The quick comparison studies of the voxel backend run in-process through the registry, checked
//! against independent numbers: the L2/H1 rates of trilinear elements measured from the rows, the
//! cantilever against Euler–Bernoulli beam theory, the CSV round trip with the stated header, and
//! a few stability cells whose outcome is known. No timing is asserted.

use cleave_registry::{backend, backends};
use cleave_testkit::compare::{CSV_HEADER, Problem, Row, Silent, StudyPlan, observed_rates, parse_csv, run_study};
use cleave_testkit::stability::{Start, Verdict, cells, run_cell};

fn quick_rows(problem: Problem) -> Vec<Row> {
    let voxel = backend("voxel").expect("voxel is registered");
    let outcome = run_study(voxel.as_ref(), "trilinear", problem, &StudyPlan::quick(problem), &mut Silent);
    println!("{}: stopped by {}", problem.key(), outcome.stop_reason);
    outcome.rows
}

#[test]
fn voxel_is_registered_once_with_one_variant() {
    let names: Vec<String> = backends().iter().map(|b| b.name().to_string()).collect();
    assert_eq!(names.iter().filter(|n| *n == "voxel").count(), 1, "{names:?}");
    assert_eq!(backend("voxel").unwrap().variants(), vec!["trilinear".to_string()]);
}

#[test]
fn quick_mms_and_cantilever_rows_converge_and_parse() {
    let mut rows = quick_rows(Problem::MmsSin111);
    let mms_levels: Vec<usize> = rows.iter().map(|r| r.n).collect();
    assert_eq!(mms_levels, vec![2, 4, 8], "the quick MMS study runs n = 2, 4, 8");
    rows.extend(quick_rows(Problem::Cantilever));

    // The CSV as the harness writes it parses back to the same rows under the stated header.
    let text: String =
        std::iter::once(CSV_HEADER.to_string()).chain(rows.iter().map(Row::to_csv)).collect::<Vec<_>>().join("\n");
    let parsed = parse_csv(&text).expect("CSV parses");
    assert_eq!(parsed.len(), rows.len());
    assert!(CSV_HEADER.starts_with("problem,backend,variant,n,dofs,elements,nnz,l2_rel_error,h1_rel_error,tip_uz_avg,tip_uz_point,strain_energy,seconds_setup,seconds_assemble,seconds_solve,seconds_total,peak_rss_mb"));

    // Trilinear elements: L2 rate 2, H1 rate 1 (benchmarks.md §1), measured from the parsed rows.
    let mms: Vec<&Row> = parsed.iter().filter(|r| r.problem == "mms-sin111").collect();
    let l2 = observed_rates(&mms, |r| r.l2_rel_error);
    let h1 = observed_rates(&mms, |r| r.h1_rel_error);
    for (r, (a, b)) in mms.iter().zip(l2.iter().zip(&h1)) {
        println!(
            "n = {}: dofs {} L2 {:.3e} (rate {a:?}) H1 {:.3e} (rate {b:?})",
            r.n,
            r.dofs,
            r.l2_rel_error.unwrap(),
            r.h1_rel_error.unwrap()
        );
    }
    let (l2_last, h1_last) = (l2.last().unwrap().unwrap(), h1.last().unwrap().unwrap());
    assert!((l2_last - 2.0).abs() < 0.2, "L2 rate 4 → 8 is {l2_last}, expected ≈ 2");
    assert!((h1_last - 1.0).abs() < 0.2, "H1 rate 4 → 8 is {h1_last}, expected ≈ 1");
    // DOFs of an n³ grid of shared nodes: 3 (n+1)³.
    for r in &mms {
        assert_eq!(r.dofs, 3 * (r.n + 1).pow(3));
        assert_eq!(r.elements, r.n.pow(3));
    }

    // Cantilever: deflection grows towards Euler–Bernoulli's q L⁴/(8 E I) = 3.767 m (the 3D
    // answer is a few percent larger; coarse trilinear cubes are too stiff).
    let beam: Vec<&Row> = parsed.iter().filter(|r| r.problem == "cantilever").collect();
    assert_eq!(beam.iter().map(|r| r.n).collect::<Vec<_>>(), vec![1, 2, 4]);
    let beam_theory = 1000.0 * 9.81 * 4f64.powi(4) / (8.0 * 1e6 / 12.0);
    for w in beam.windows(2) {
        assert!(w[1].tip_uz_avg.unwrap() < w[0].tip_uz_avg.unwrap(), "deflection must grow");
    }
    let finest = -beam.last().unwrap().tip_uz_avg.unwrap();
    assert!(finest > 0.75 * beam_theory && finest < 1.1 * beam_theory, "tip {finest} m vs beam theory {beam_theory} m");
    // ½ fᵀu of a uniform load q over the beam with deflection w(x) of Euler–Bernoulli is
    // q² L⁵ / (40 E I); again the FE value approaches from below.
    let energy = beam.last().unwrap().strain_energy.unwrap();
    let q: f64 = 1000.0 * 9.81;
    let beam_energy = q * q * 4f64.powi(5) / (40.0 * 1e6 / 12.0);
    println!("tip {finest:.4} m (beam theory {beam_theory:.4}), energy {energy:.4e} J (beam theory {beam_energy:.4e})");
    assert!(energy > 0.7 * beam_energy && energy < 1.1 * beam_energy);
}

#[test]
fn stability_cells_pass_or_name_their_failure() {
    let voxel = backend("voxel").unwrap();
    let all = cells();
    assert_eq!(all.len(), 4 * 5 * 3 + 3, "the §4 grid plus three extreme cases");
    let moderate = all
        .iter()
        .find(|c| {
            c.youngs_modulus == 1e6 && c.poisson_ratio == 0.3 && c.time_step == 1.0 / 60.0 && c.start == Start::Rest
        })
        .unwrap();
    let result = run_cell(voxel.as_ref(), "trilinear", *moderate, 30);
    println!("{:?}: {} (max energy factor {:.4})", moderate, result.verdict, result.max_energy_factor);
    assert_eq!(result.verdict, Verdict::Pass);
    assert_eq!(result.steps_done, 30);
    let sliver = all.iter().find(|c| c.case() == "sliver").unwrap();
    let result = run_cell(voxel.as_ref(), "trilinear", *sliver, 30);
    assert!(
        matches!(result.verdict, Verdict::NotApplicable(ref why) if why.contains("equal cubes")),
        "{}",
        result.verdict
    );
    // The pre-inverted cube starts inverted: the run reports it, whatever its verdict.
    let inverted = all.iter().find(|c| c.case() == "pre-inverted").unwrap();
    let result = run_cell(voxel.as_ref(), "trilinear", *inverted, 30);
    println!("pre-inverted: {} (max inverted {})", result.verdict, result.max_inverted);
    assert!(result.max_inverted >= 1);
}

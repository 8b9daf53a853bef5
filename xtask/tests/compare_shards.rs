//! `cargo xtask compare --shard I/N` and `--merge`: two shards of a quick comparison split the
//! work between them without overlap, and their merge reports the same studies, levels and
//! errors as one unsharded run of the same selection; a merge refuses a missing shard and
//! shards run with different selections.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

fn xtask(args: &[&str], out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .current_dir(workspace())
        .args(["compare", "--quick", "--quiet"])
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// The deterministic columns of compare.csv (problem, method, level, DOFs, errors, tip values;
/// no timings), one string per row.
fn study_rows(dir: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(dir.join("compare.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep = ["problem", "backend", "variant", "n", "dofs", "elements", "l2_rel_error", "h1_rel_error", "tip_uz_avg"];
    let columns: Vec<usize> = keep.iter().map(|k| header.iter().position(|h| h == k).unwrap()).collect();
    lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            columns.iter().map(|&c| cells[c]).collect::<Vec<_>>().join(",")
        })
        .collect()
}

/// The methods with a Table 1 row.
fn table1_methods(dir: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(dir.join("table1.csv")).unwrap();
    text.lines().skip(1).map(|l| l.split(',').take(2).collect::<Vec<_>>().join("/")).collect()
}

#[test]
fn two_shards_merged_report_what_one_run_reports() {
    let dir = tempfile::tempdir().unwrap();
    let [whole, first, second, merged] = ["whole", "first", "second", "merged"].map(|d| dir.path().join(d));
    let selection = ["--problem", "mms", "cantilever", "table1", "--backend", "voxel"];
    for (out, shard) in [(&whole, None), (&first, Some("1/2")), (&second, Some("2/2"))] {
        let mut args = selection.to_vec();
        if let Some(s) = shard {
            args.extend(["--shard", s]);
        }
        let output = xtask(&args, out);
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    }
    let (a, b) = (study_rows(&first), study_rows(&second));
    assert!(!a.is_empty() && !b.is_empty(), "each shard takes some studies: {a:?} {b:?}");
    assert!(a.is_disjoint(&b), "shards overlap: {:?}", a.intersection(&b).collect::<Vec<_>>());
    // Three studies and one Table 1 timing, round robin: the Table 1 unit is the second shard's.
    assert!(table1_methods(&first).is_empty());
    assert_eq!(table1_methods(&second), table1_methods(&whole));

    let output = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .current_dir(workspace())
        .args(["compare", "--quiet", "--merge"])
        .args([&first, &second])
        .arg("--out")
        .arg(&merged)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let union: BTreeSet<String> = a.union(&b).cloned().collect();
    assert_eq!(study_rows(&merged), union);
    assert_eq!(study_rows(&merged), study_rows(&whole), "the merge reports what one run reports");
    assert_eq!(table1_methods(&merged), table1_methods(&whole));
    let report = std::fs::read_to_string(merged.join("compare.md")).unwrap();
    let stops = |text: &str| text.lines().filter(|l| l.starts_with("- voxel/") && l.contains("stopped by")).count();
    let whole_report = std::fs::read_to_string(whole.join("compare.md")).unwrap();
    assert_eq!(stops(&report), stops(&whole_report), "every study's stop line is merged");
    assert_eq!(stops(&report), 3);
    assert!(report.contains("merging 2 shards"));
}

#[test]
fn a_merge_refuses_a_missing_shard_and_shards_of_different_selections() {
    let dir = tempfile::tempdir().unwrap();
    let [first, other] = ["first", "other"].map(|d| dir.path().join(d));
    let ok = xtask(&["--problem", "cantilever", "--backend", "voxel", "--shard", "1/2"], &first);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let ok = xtask(&["--problem", "mms", "--backend", "voxel", "--shard", "2/2"], &other);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let merge = |dirs: &[&PathBuf]| {
        Command::new(env!("CARGO_BIN_EXE_xtask"))
            .current_dir(workspace())
            .args(["compare", "--quiet", "--merge"])
            .args(dirs)
            .arg("--out")
            .arg(dir.path().join("merged"))
            .output()
            .unwrap()
    };
    let missing = merge(&[&first]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("lacks shard(s) 2/2"));
    let mixed = merge(&[&first, &other]);
    assert!(!mixed.status.success());
    assert!(String::from_utf8_lossy(&mixed.stderr).contains("another selection"));
}

#!/usr/bin/env python3
"""Checks that the CSV outputs of `cargo xtask compare --quick` and `cargo xtask stability --quick`
parse: the stated header, numbers (or empty cells) where numbers belong, every quick study present,
the whole stability grid with a verdict in every cell, a crack that opens and a cut that adds no
energy in the cut-cantilever rows, Table 1 timings, and the cut table of
bunny_slice.ron (a virtualnode row that cut into at least three pieces and kept volume and mass
to 1e-12). Usage: check_results.py DIR."""
import csv
import math
import sys
from pathlib import Path

COMPARE_HEADER = ("problem,backend,variant,n,dofs,elements,nnz,l2_rel_error,h1_rel_error,tip_uz_avg,"
                  "tip_uz_point,strain_energy,seconds_setup,seconds_assemble,seconds_solve,seconds_total,"
                  "peak_rss_mb").split(",")
# §4's grid, the three extreme cells, and the cut beam at E in {1e6, 1e12}, nu in {0.3, 0.4999}
# with the crack on a node plane and 1e-6 h off it (not-applicable cells count: every method
# has every cell).
STABILITY_CELLS = 4 * 5 * 3 + 3 + 2 * 2 * 2


def number(text, column, line):
    if text == "":
        return None
    value = float(text)
    if not math.isfinite(value):
        raise SystemExit(f"line {line}: column {column} is not finite: {text!r}")
    return value


def main(directory):
    directory = Path(directory)
    with open(directory / "compare.csv", newline="") as f:
        reader = csv.DictReader(f)
        if reader.fieldnames[: len(COMPARE_HEADER)] != COMPARE_HEADER:
            raise SystemExit(f"compare.csv header {reader.fieldnames} does not start with {COMPARE_HEADER}")
        rows = list(reader)
    for i, row in enumerate(rows, start=2):
        for column in COMPARE_HEADER[3:]:
            number(row[column], column, i)
        if int(row["dofs"]) <= 0:
            raise SystemExit(f"compare.csv line {i}: no DOFs")
    problems = {r["problem"] for r in rows if r["backend"] == "voxel"}
    expected = {"mms-sin111", "mms-cos123", "cantilever", "dynamic", "cut-cantilever", "cut-dynamic"}
    if problems != expected:
        raise SystemExit(f"voxel rows cover {sorted(problems)}, expected {sorted(expected)}")
    for i, row in enumerate(rows, start=2):
        if row["problem"] == "cut-cantilever" and not number(row["crack_opening"], "crack_opening", i) > 0:
            raise SystemExit(f"compare.csv line {i}: the crack of {row['backend']} does not open")
        if row["problem"] == "cut-dynamic":
            before = number(row["energy_before_cut"], "energy_before_cut", i)
            after = number(row["energy_after_cut"], "energy_after_cut", i)
            if after - before > 1e-9 * abs(before):
                raise SystemExit(f"compare.csv line {i}: the cut added energy ({before} -> {after} J)")
    l2 = [float(r["l2_rel_error"]) for r in rows if r["problem"] == "mms-sin111" and r["backend"] == "voxel"]
    if not all(a > b for a, b in zip(l2, l2[1:])):
        raise SystemExit(f"voxel L2 errors do not decrease: {l2}")

    with open(directory / "stability.csv", newline="") as f:
        cells = list(csv.DictReader(f))
    methods = {(c["backend"], c["variant"]) for c in cells}
    for method in methods:
        own = [c for c in cells if (c["backend"], c["variant"]) == method]
        if len(own) != STABILITY_CELLS:
            raise SystemExit(f"stability.csv has {len(own)} cells for {method}, expected {STABILITY_CELLS}")
        for c in own:
            if c["passed"] not in ("true", "false") or not c["verdict"]:
                raise SystemExit(f"stability.csv: malformed cell {c}")
            number(c["max_energy_factor"], "max_energy_factor", 0)

    with open(directory / "table1.csv", newline="") as f:
        table1 = list(csv.DictReader(f))
    for t in table1:
        if t["error"]:
            raise SystemExit(f"table1.csv: {t['backend']}/{t['variant']} failed: {t['error']}")
        for column in ("integration", "pattern", "assembly", "solve", "search"):
            if number(t[column], column, 0) is None:
                raise SystemExit(f"table1.csv: {t['backend']}/{t['variant']} has no {column}")
    if not any(t["backend"] == "voxel" for t in table1):
        raise SystemExit("table1.csv has no voxel row")

    with open(directory / "cutting.csv", newline="") as f:
        cuts = {c["backend"]: c for c in csv.DictReader(f)}
    vn = cuts.get("virtualnode")
    if vn is None:
        raise SystemExit(f"cutting.csv has no virtualnode row (rows: {sorted(cuts)})")
    for column in ("volume_drift", "mass_drift"):
        if abs(number(vn[column], column, 0)) > 1e-12:
            raise SystemExit(f"cutting.csv: virtualnode {column} = {vn[column]} > 1e-12")
    if int(vn["pieces"]) < 3 or int(vn["changes"]) <= 0 or int(vn["elements_after"]) <= int(vn["elements_before"]):
        raise SystemExit(f"cutting.csv: virtualnode row does not show the cuts: {vn}")
    print(f"results parse: {len(rows)} compare rows, {len(cells)} stability cells for {len(methods)} method(s), "
          f"{len(table1)} Table 1 rows, {len(cuts)} cut row(s)")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "target/ci")

//! `cargo xtask compare`: runs the budgeted refinement studies of every registered backend
//! (`cleave_registry`), appends each finished run to the CSV at once, times kaufmann2008's
//! Table 1, runs the cutting scene on every backend that can cut (`crate::cutting`), and writes
//! the Markdown report and the plots. The studies themselves live in `cleave_testkit::compare`.
//! An invocation redoes only what it selects: rows, Table 1 timings, cut rows and the lines of
//! "How each study stopped" of other backends and problems are kept from the previous files.

use crate::cutting::{self, CutRow};
use crate::machine::{RssProbe, machine_line};
use crate::plots;
use anyhow::{Context, Result, bail};
use cleave_registry::registered;
use cleave_testkit::compare::{
    CSV_HEADER, CUT_DYNAMIC_CUT_STEP, CUT_DYNAMIC_STEPS, DYNAMIC_STEPS, KAUFMANN2008_TABLE1, Problem, Row,
    StudyObserver, StudyPlan, Table1Timings, TipReference, cantilever_reference, cut_cantilever_reference,
    observed_rates, parse_csv, run_study, self_consistency, table1_timings, time_to_accuracy,
};
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt::Write as _;
use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Parsed arguments of `cargo xtask compare`.
pub struct CompareArgs {
    /// Small levels only (CI).
    pub quick: bool,
    /// Any of "mms", "cantilever", "dynamic", "cut-cantilever" (static and dynamic), "table1",
    /// "cutting", or "all".
    pub problems: Vec<String>,
    /// Backends to run (empty = all registered).
    pub backends: Vec<String>,
    /// Seconds per (method, problem) study.
    pub budget: f64,
    /// Output directory.
    pub out: PathBuf,
    /// The command as typed, for the report.
    pub command: String,
    /// No progress bar.
    pub quiet: bool,
    /// Run only this slice of the work list (its directory then holds only the slice).
    pub shard: Option<Shard>,
}

/// What one invocation runs.
struct Selection {
    /// Refinement studies, in report order.
    problems: Vec<Problem>,
    /// kaufmann2008 Table 1 timings.
    table1: bool,
    /// The cutting scene on the backends that can cut.
    cutting: bool,
}

fn selection(names: &[String]) -> Result<Selection> {
    let (mut problems, mut table1, mut cutting) = (Vec::new(), false, false);
    for name in names {
        match name.as_str() {
            "all" => {
                problems.extend(Problem::ALL);
                table1 = true;
                cutting = true;
            }
            "mms" => problems.extend([Problem::MmsSin111, Problem::MmsCos123]),
            "cantilever" => problems.push(Problem::Cantilever),
            "dynamic" => problems.push(Problem::Dynamic),
            "cut-cantilever" => problems.extend([Problem::CutCantilever, Problem::CutDynamic]),
            "table1" => table1 = true,
            "cutting" => cutting = true,
            other => bail!(
                "unknown problem {other:?}: expected mms, cantilever, dynamic, cut-cantilever, table1, cutting or all"
            ),
        }
    }
    let problems = Problem::ALL.into_iter().filter(|p| problems.contains(p)).collect();
    Ok(Selection { problems, table1, cutting })
}

/// Header of `table1.csv`: one row per method, kept for methods an invocation does not time.
const TABLE1_HEADER: &str = "backend,variant,integration,pattern,assembly,solve,search,dofs,nnz,factor_nnz,error";

type Table1Row = (String, String, Result<Table1Timings, String>);

fn table1_to_csv((backend, variant, timing): &Table1Row) -> String {
    match timing {
        Ok(t) => format!(
            "{backend},{variant},{:.9e},{:.9e},{:.9e},{:.9e},{:.9e},{},{},{},",
            t.integration, t.pattern, t.assembly, t.solve, t.search, t.dofs, t.nnz, t.factor_nnz
        ),
        Err(e) => format!("{backend},{variant},,,,,,,,,{}", e.replace([',', '\n'], ";")),
    }
}

fn table1_from_csv(line: &str) -> Option<Table1Row> {
    let f: Vec<&str> = line.trim_end().splitn(11, ',').collect();
    let [backend, variant, integration, pattern, assembly, solve, search, dofs, nnz, factor_nnz, error] = f.as_slice()
    else {
        return None;
    };
    let timing = if error.is_empty() {
        Ok(Table1Timings {
            integration: integration.parse().ok()?,
            pattern: pattern.parse().ok()?,
            assembly: assembly.parse().ok()?,
            solve: solve.parse().ok()?,
            search: search.parse().ok()?,
            dofs: dofs.parse().ok()?,
            nnz: nnz.parse().ok()?,
            factor_nnz: factor_nnz.parse().ok()?,
        })
    } else {
        Err(error.to_string())
    };
    Some((backend.to_string(), variant.to_string(), timing))
}

fn read_table1(path: &Path) -> Vec<Table1Row> {
    let Ok(text) = fs::read_to_string(path) else { return Vec::new() };
    let mut lines = text.lines();
    if lines.next().map(str::trim_end) != Some(TABLE1_HEADER) {
        return Vec::new();
    }
    lines.filter_map(table1_from_csv).collect()
}

/// The lines of "How each study stopped" in a previous report, as `(method, problem key, line)`.
fn previous_stops(path: &Path) -> Vec<(String, String, String)> {
    let Ok(text) = fs::read_to_string(path) else { return Vec::new() };
    text.lines()
        .skip_while(|l| l.trim() != "## How each study stopped")
        .skip(1)
        .take_while(|l| !l.starts_with("## "))
        .filter_map(|l| {
            let line = l.strip_prefix("- ")?;
            let (head, _) = line.split_once(':')?;
            let (method, problem) = head.split_once(' ')?;
            Some((method.to_string(), problem.to_string(), line.to_string()))
        })
        .collect()
}

/// The registered backends named in `names` (all if empty); unknown names are an error that
/// lists the registered ones.
pub fn selected_backends(names: &[String]) -> Result<Vec<Box<dyn cleave_registry::Backend>>> {
    let all = registered();
    let registered: Vec<String> = all.iter().map(|b| b.name().to_string()).collect();
    if let Some(unknown) = names.iter().find(|n| !registered.contains(n)) {
        bail!("no backend {unknown:?} is registered (registered: {})", registered.join(", "));
    }
    Ok(all.into_iter().filter(|b| names.is_empty() || names.iter().any(|n| n == b.name())).collect())
}

/// Writes rows to the CSV as they finish, flushing each.
struct CsvAppender {
    file: File,
}

impl CsvAppender {
    /// Keeps the rows of `path` that this invocation does not redo, rewrites the file with them,
    /// and opens it for appending.
    fn open(path: &Path, redo: &dyn Fn(&Row) -> bool) -> Result<(Self, Vec<Row>)> {
        let kept: Vec<Row> = match fs::read_to_string(path) {
            Ok(text) => {
                parse_csv(&text).map(|rows| rows.into_iter().filter(|r| !redo(r)).collect()).unwrap_or_default()
            }
            Err(_) => Vec::new(),
        };
        let mut text = format!("{CSV_HEADER}\n");
        for r in &kept {
            text.push_str(&r.to_csv());
            text.push('\n');
        }
        fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        let file = OpenOptions::new().append(true).open(path).with_context(|| format!("opening {}", path.display()))?;
        Ok((Self { file }, kept))
    }

    fn append(&mut self, row: &Row) -> std::io::Result<()> {
        writeln!(self.file, "{}", row.to_csv())?;
        self.file.flush()
    }
}

struct Observer<'a> {
    csv: &'a mut CsvAppender,
    bar: &'a ProgressBar,
    rss: RssProbe,
    label: String,
    write_error: Option<std::io::Error>,
}

impl StudyObserver for Observer<'_> {
    fn before_level(&mut self, problem: Problem, n: usize, repetitions: usize) {
        self.bar.set_message(format!("{} {} n = {n} (×{repetitions})", self.label, problem.key()));
        self.rss.reset();
    }

    fn peak_rss_mb(&mut self) -> Option<f64> {
        self.rss.peak_mb()
    }

    fn row_done(&mut self, row: &Row) {
        if let Err(e) = self.csv.append(row) {
            self.write_error.get_or_insert(e);
        }
        let line = format!(
            "  {} {} n = {:>3}: {} DOFs, {:.3} s{}",
            row.method(),
            row.problem,
            row.n,
            row.dofs,
            row.seconds_total.unwrap_or(f64::NAN),
            match (row.l2_rel_error, row.tip_uz_avg) {
                (Some(e), _) => format!(", L2 {e:.3e}"),
                (_, Some(t)) => format!(", tip {t:.5} m"),
                _ => String::new(),
            }
        );
        // A hidden bar (no terminal, --quiet) drops println: write the line to stderr instead.
        if self.bar.is_hidden() {
            eprintln!("{line}");
        } else {
            self.bar.println(line);
        }
    }
}

/// One slice of the work list, `I/N` on the command line (1-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard's index, 0-based.
    pub index: usize,
    /// The number of shards.
    pub count: usize,
}

impl Shard {
    /// Parses `I/N` with 1 ≤ I ≤ N.
    pub fn parse(text: &str) -> Result<Self> {
        let parsed = text
            .split_once('/')
            .and_then(|(i, n)| Some((i.trim().parse::<usize>().ok()?, n.trim().parse::<usize>().ok()?)));
        match parsed {
            Some((i, n)) if n >= 1 && (1..=n).contains(&i) => Ok(Self { index: i - 1, count: n }),
            _ => bail!("--shard expects I/N with 1 ≤ I ≤ N (for example 2/4), got {text:?}"),
        }
    }

    /// Whether the `position`-th unit of the work list is this shard's (round robin, so every
    /// shard gets a mix of cheap and costly studies).
    fn takes(&self, position: usize) -> bool {
        position % self.count == self.index
    }
}

/// One unit of `compare`'s work list: what a shard takes or leaves.
#[derive(Clone, Debug, PartialEq)]
enum Unit {
    /// A refinement study of one method on one problem.
    Study { backend: usize, variant: String, problem: Problem },
    /// One method's Table 1 timing.
    Table1 { backend: usize, variant: String },
    /// The cutting scene on one backend.
    Cutting { backend: usize },
}

/// The whole work list of a selection, in a fixed order (studies by backend, variant and problem;
/// Table 1 by method; cutting by backend): every shard of one invocation computes the same list.
fn work_list(selection: &Selection, chosen: &[Box<dyn cleave_registry::Backend>]) -> Vec<Unit> {
    let mut units = Vec::new();
    for (b, backend) in chosen.iter().enumerate() {
        for variant in backend.variants() {
            for &problem in &selection.problems {
                // The cut problems run only for methods that cut.
                if !problem.needs_cutting() || backend.cuts(&variant) {
                    units.push(Unit::Study { backend: b, variant: variant.clone(), problem });
                }
            }
        }
    }
    if selection.table1 {
        for (b, backend) in chosen.iter().enumerate() {
            units.extend(backend.variants().into_iter().map(|variant| Unit::Table1 { backend: b, variant }));
        }
    }
    if selection.cutting {
        for (b, backend) in chosen.iter().enumerate() {
            if backend.capabilities().cut {
                units.push(Unit::Cutting { backend: b });
            }
        }
    }
    units
}

impl Unit {
    /// A stable name for the unit (the fingerprint of a work list is made of them).
    fn label(&self, chosen: &[Box<dyn cleave_registry::Backend>]) -> String {
        match self {
            Unit::Study { backend, variant, problem } => {
                format!("study {}/{variant} {}", chosen[*backend].name(), problem.key())
            }
            Unit::Table1 { backend, variant } => format!("table1 {}/{variant}", chosen[*backend].name()),
            Unit::Cutting { backend } => format!("cutting {}", chosen[*backend].name()),
        }
    }
}

/// FNV-1a of the work list's labels and the level plan: shards of one split agree on it, so a
/// merge can refuse shards that were run with different selections.
fn fingerprint(labels: &[String], quick: bool, budget: f64) -> String {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let text = format!("{}|quick={quick}|budget={budget}", labels.join(";"));
    for byte in text.bytes() {
        hash ^= u64::from(byte);
        hash = hash.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{hash:016x}")
}

/// The file a shard writes beside its rows, read back by `--merge`.
const SHARD_FILE: &str = "shard.txt";

/// Where the rows of a report came from: the machine and the command(s).
struct Provenance {
    /// The machine line(s).
    machine: String,
    /// The command as typed, in Markdown code spans (and the shards' commands for a merge).
    command: String,
    /// What the cut cantilever section says about the load its timings ran under.
    cut_load: String,
}

/// Runs `cargo xtask compare`.
pub fn compare(args: CompareArgs) -> Result<()> {
    let selection = selection(&args.problems)?;
    let chosen = selected_backends(&args.backends)?;
    fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let all_units = work_list(&selection, &chosen);
    let labels: Vec<String> = all_units.iter().map(|u| u.label(&chosen)).collect();
    let units: Vec<Unit> = all_units
        .into_iter()
        .enumerate()
        .filter(|(i, _)| args.shard.is_none_or(|s| s.takes(*i)))
        .map(|(_, u)| u)
        .collect();
    let method_of = |b: usize, v: &str| (chosen[b].name().to_string(), v.to_string());
    let studied: Vec<(String, String, &'static str)> = units
        .iter()
        .filter_map(|u| match u {
            Unit::Study { backend, variant, problem } => {
                let (b, v) = method_of(*backend, variant);
                Some((b, v, problem.key()))
            }
            _ => None,
        })
        .collect();
    // A shard's directory holds its own slice only; otherwise what is not redone is kept.
    let sharded = args.shard.is_some();
    let redo =
        |r: &Row| sharded || studied.iter().any(|(b, v, p)| *b == r.backend && *v == r.variant && *p == r.problem);
    let csv_path = args.out.join("compare.csv");
    let (mut csv, kept) = CsvAppender::open(&csv_path, &redo)?;
    let md_path = args.out.join("compare.md");
    let mut stops: Vec<String> = if sharded { Vec::new() } else { previous_stops(&md_path) }
        .into_iter()
        .filter(|(method, problem, _)| !studied.iter().any(|(b, v, p)| *method == format!("{b}/{v}") && p == problem))
        .map(|(_, _, line)| line)
        .collect();

    let bar = if args.quiet { ProgressBar::hidden() } else { ProgressBar::new(units.len() as u64) };
    bar.set_style(
        ProgressStyle::with_template("{bar:30.cyan/blue} {pos}/{len} units  {elapsed_precise}  {msg}")
            .expect("static template")
            .progress_chars("=> "),
    );
    let table1_path = args.out.join("table1.csv");
    let cutting_path = args.out.join("cutting.csv");
    let mut rows = kept;
    let mut table1: Vec<Table1Row> = if sharded { Vec::new() } else { read_table1(&table1_path) };
    let mut cut_rows: Vec<CutRow> = if sharded { Vec::new() } else { cutting::read_rows(&cutting_path) };
    let mut cut_errors = Vec::new();
    for unit in &units {
        match unit {
            Unit::Study { backend, variant, problem } => {
                let backend = &chosen[*backend];
                let plan = if args.quick { StudyPlan::quick(*problem) } else { StudyPlan::full(args.budget) };
                let label = format!("{}/{variant}", backend.name());
                let mut observer = Observer {
                    csv: &mut csv,
                    bar: &bar,
                    rss: RssProbe::new(),
                    label: label.clone(),
                    write_error: None,
                };
                let outcome = run_study(backend.as_ref(), variant, *problem, &plan, &mut observer);
                if let Some(e) = observer.write_error {
                    return Err(e).with_context(|| format!("appending to {}", csv_path.display()));
                }
                stops.push(format!(
                    "{label} {}: {} levels, stopped by {}",
                    problem.key(),
                    outcome.rows.len(),
                    outcome.stop_reason
                ));
                rows.extend(outcome.rows);
            }
            Unit::Table1 { backend, variant } => {
                let backend = &chosen[*backend];
                bar.set_message(format!("Table 1 timings of {}/{variant}", backend.name()));
                table1.retain(|(b, v, _)| !(b == backend.name() && v == variant));
                let timing = table1_timings(backend.as_ref(), variant, 3);
                table1.push((backend.name().to_string(), variant.clone(), timing.map_err(|e| e.to_string())));
                write_table1(&table1_path, &table1)?;
            }
            Unit::Cutting { backend } => {
                let name = chosen[*backend].name();
                bar.set_message(format!("cutting {} on {name}", cutting::SCENE));
                cut_rows.retain(|r| r.backend != name);
                match cutting::run(name) {
                    Ok(row) => cut_rows.push(row),
                    Err(e) => {
                        let chain: Vec<String> = e.chain().map(ToString::to_string).collect();
                        cut_errors.push((name.to_string(), chain.join(": ")));
                    }
                }
                cutting::write_rows(&cutting_path, &cut_rows)?;
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    if sharded {
        // Empty files for what this shard did not take, so a merge reads every shard alike.
        write_table1(&table1_path, &table1)?;
        cutting::write_rows(&cutting_path, &cut_rows)?;
    }
    let ran_cut = studied.iter().any(|(_, _, p)| *p == Problem::CutCantilever.key());
    let provenance = Provenance {
        machine: machine_line(),
        command: format!("`{}`", args.command),
        cut_load: if ran_cut {
            crate::machine::load_line()
        } else {
            "These rows are from an earlier invocation than the command above.".to_string()
        },
    };
    if let Some(shard) = args.shard {
        let manifest = format!(
            "shard {}/{}\n{}\n{}\nwork list {} ({} units)\n",
            shard.index + 1,
            shard.count,
            provenance.machine,
            args.command,
            fingerprint(&labels, args.quick, args.budget),
            labels.len()
        );
        let path = args.out.join(SHARD_FILE);
        fs::write(&path, manifest).with_context(|| format!("writing {}", path.display()))?;
    }
    write_report(&args, &provenance, &rows, &stops, &table1, &cut_rows, &cut_errors)
}

/// `cargo xtask compare --merge DIR…`: the report and plots of many shards' rows. Refuses shards
/// of different splits, a missing or repeated shard, and rows that two shards both hold.
pub fn merge(args: CompareArgs, dirs: &[PathBuf]) -> Result<()> {
    let mut rows: Vec<Row> = Vec::new();
    let mut stops = Vec::new();
    let mut table1: Vec<Table1Row> = Vec::new();
    let mut cut_rows: Vec<CutRow> = Vec::new();
    let mut machines: Vec<String> = Vec::new();
    let mut commands = Vec::new();
    let mut seen: Vec<(Shard, &Path)> = Vec::new();
    let mut owner: Vec<(String, &Path)> = Vec::new();
    let mut work_list_line: Option<(String, String)> = None;
    for dir in dirs {
        let manifest_path = dir.join(SHARD_FILE);
        let manifest = fs::read_to_string(&manifest_path)
            .with_context(|| format!("{} is not a shard's output ({} is missing)", dir.display(), SHARD_FILE))?;
        let mut lines = manifest.lines();
        let shard = lines
            .next()
            .and_then(|l| l.strip_prefix("shard "))
            .map(Shard::parse)
            .transpose()?
            .with_context(|| format!("{}: the first line should be \"shard I/N\"", manifest_path.display()))?;
        if let Some((other, other_dir)) = seen.iter().find(|(s, _)| s.count != shard.count || s.index == shard.index) {
            bail!(
                "{} is shard {}/{} and {} is shard {}/{}: a merge takes each shard of one split once",
                other_dir.display(),
                other.index + 1,
                other.count,
                dir.display(),
                shard.index + 1,
                shard.count
            );
        }
        seen.push((shard, dir));
        let machine = lines.next().unwrap_or_default().to_string();
        if !machines.contains(&machine) {
            machines.push(machine);
        }
        let command = lines.next().unwrap_or_default();
        commands.push(format!("`{command}`"));
        let list = lines.next().unwrap_or_default().to_string();
        match &work_list_line {
            None => work_list_line = Some((list, command.to_string())),
            Some((first, first_command)) if *first != list => bail!(
                "{} was run with another selection than the first shard ({first_command:?} against {command:?}): \
                 every shard of a split must be given the same --problem, --backend, --quick and --budget",
                dir.display()
            ),
            Some(_) => {}
        }

        let csv_path = dir.join("compare.csv");
        let text = fs::read_to_string(&csv_path).with_context(|| format!("reading {}", csv_path.display()))?;
        let shard_rows = parse_csv(&text).map_err(|e| anyhow::anyhow!("{}: {e}", csv_path.display()))?;
        let mut claim = |key: String| -> Result<()> {
            if let Some((_, first)) = owner.iter().find(|(k, _)| *k == key) {
                bail!("{key} is in both {} and {}: the shards overlap", first.display(), dir.display());
            }
            owner.push((key, dir));
            Ok(())
        };
        let mut studies: Vec<String> =
            shard_rows.iter().map(|r| format!("study {} {}", r.method(), r.problem)).collect();
        studies.dedup();
        for key in studies {
            claim(key)?;
        }
        let shard_table1 = read_table1(&dir.join("table1.csv"));
        for (b, v, _) in &shard_table1 {
            claim(format!("Table 1 of {b}/{v}"))?;
        }
        let shard_cuts = cutting::read_rows(&dir.join("cutting.csv"));
        for r in &shard_cuts {
            claim(format!("the cutting scene on {}", r.backend))?;
        }
        rows.extend(shard_rows);
        table1.extend(shard_table1);
        cut_rows.extend(shard_cuts);
        stops.extend(previous_stops(&dir.join("compare.md")).into_iter().map(|(_, _, line)| line));
    }
    let count = seen.first().map_or(0, |(s, _)| s.count);
    if seen.len() != count {
        let missing: Vec<String> = (1..=count)
            .filter(|i| !seen.iter().any(|(s, _)| s.index + 1 == *i))
            .map(|i| format!("{i}/{count}"))
            .collect();
        bail!("the merge lacks shard(s) {} of the split", missing.join(", "));
    }
    fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let csv_path = args.out.join("compare.csv");
    let text: String =
        std::iter::once(CSV_HEADER.to_string()).chain(rows.iter().map(Row::to_csv)).collect::<Vec<_>>().join("\n");
    fs::write(&csv_path, text + "\n").with_context(|| format!("writing {}", csv_path.display()))?;
    write_table1(&args.out.join("table1.csv"), &table1)?;
    cutting::write_rows(&args.out.join("cutting.csv"), &cut_rows)?;
    let provenance = Provenance {
        machine: machines.join("  \n"),
        command: format!("`{}`, merging {count} shards: {}", args.command, commands.join(", ")),
        cut_load: "Each shard's load average is in its own compare.md.".to_string(),
    };
    write_report(&args, &provenance, &rows, &stops, &table1, &cut_rows, &[])
}

fn write_table1(path: &Path, table1: &[Table1Row]) -> Result<()> {
    let text: String = std::iter::once(TABLE1_HEADER.to_string())
        .chain(table1.iter().map(table1_to_csv))
        .collect::<Vec<_>>()
        .join("\n");
    fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))
}

/// Writes `compare.md` and the plots of `rows` into `args.out` and prints the report.
fn write_report(
    args: &CompareArgs,
    provenance: &Provenance,
    rows: &[Row],
    stops: &[String],
    table1: &[Table1Row],
    cut_rows: &[CutRow],
    cut_errors: &[(String, String)],
) -> Result<()> {
    let registered = cleave_registry::registered();
    let order: Vec<String> = registered.iter().map(|r| r.name().to_string()).collect();
    let cannot_cut: Vec<String> =
        registered.iter().filter(|r| !r.capabilities().cut).map(|r| r.name().to_string()).collect();
    let cut_section = cutting::section(cut_rows, &order, &cannot_cut, cut_errors);
    let report = report(args, provenance, rows, stops, table1, &cut_section);
    println!("{report}");
    let md_path = args.out.join("compare.md");
    fs::write(&md_path, &report).with_context(|| format!("writing {}", md_path.display()))?;
    let written = plots::compare_plots(rows, &args.out)?;
    println!("wrote {}, {} and {}", args.out.join("compare.csv").display(), md_path.display(), written.join(", "));
    Ok(())
}

fn sci(value: Option<f64>) -> String {
    value.map_or_else(|| "—".into(), |v| format!("{v:.3e}"))
}

fn fixed(value: Option<f64>, digits: usize) -> String {
    value.map_or_else(|| "—".into(), |v| format!("{v:.digits$}"))
}

fn rate(value: Option<f64>) -> String {
    value.map_or_else(|| "".into(), |v| format!("{v:.2}"))
}

fn mb(value: Option<f64>) -> String {
    value.map_or_else(|| "—".into(), |v| format!("{v:.0}"))
}

/// Rows of one problem grouped by method, each group sorted by n, methods in first-seen order.
fn by_method(rows: &[Row], problem: Problem) -> Vec<(String, Vec<&Row>)> {
    let mut groups: Vec<(String, Vec<&Row>)> = Vec::new();
    for r in rows.iter().filter(|r| r.problem == problem.key()) {
        match groups.iter_mut().find(|(m, _)| *m == r.method()) {
            Some((_, g)) => g.push(r),
            None => groups.push((r.method(), vec![r])),
        }
    }
    for (_, g) in &mut groups {
        g.sort_by_key(|r| r.n);
    }
    groups
}

/// Whether the method `backend/variant` is consistent, from its registration (unknown methods,
/// e.g. from an old CSV, count as consistent).
pub fn method_is_consistent(method: &str) -> bool {
    let (name, variant) = method.split_once('/').unwrap_or((method, ""));
    cleave_registry::find(name).is_none_or(|b| b.is_consistent(variant))
}

/// The cantilever reference of `rows` by the rule of [`cantilever_reference`].
pub fn reference_of(rows: &[Row]) -> Option<TipReference> {
    cantilever_reference(rows, &method_is_consistent)
}

/// The relative tip error of a cantilever row against the reference.
pub fn tip_error(row: &Row, reference: &TipReference) -> Option<f64> {
    row.tip_uz_avg.map(|t| ((t - reference.value) / reference.value).abs())
}

fn report(
    args: &CompareArgs,
    provenance: &Provenance,
    rows: &[Row],
    stops: &[String],
    table1: &[Table1Row],
    cut_section: &str,
) -> String {
    let mut md = String::new();
    let w = &mut md;
    let _ = writeln!(w, "# Backend comparison\n");
    let _ = writeln!(
        w,
        "Problems of [`docs/math/benchmarks.md`](../math/benchmarks.md) §1–§3 and §5, every registered backend and \
         variant (§5: every method that cuts), refined n = 1, 2, 4, … (MMS and §5 from 2) until the per-study budget ({} s per backend, variant and \
         problem{}) would be exceeded: the next level's time is predicted as the last one's times the last growth \
         factor clamped to [8, 64]. Raw rows: [`compare.csv`](compare.csv) (one per run, appended as each \
         finishes).\n",
        args.budget,
        if args.quick { "; `--quick` caps the levels instead" } else { "" }
    );
    let header = format!(
        "{}  \nCommand: {} (release build). Timings are wall-clock medians of 3 repetitions, or of 1 for \
         runs predicted to take over 3 s (column *reps*). *setup* = building the discretization, loads, \
         Dirichlet data, sparsity pattern and symbolic factorization; *assemble* = matrix values; *solve* = \
         numeric Cholesky factorization and solve; *total* = the whole run without error evaluation. Peak RSS \
         is the process's high-water mark reset before each level (`/proc/self/clear_refs`), so it includes \
         the harness itself.\n",
        provenance.machine, provenance.command
    );
    let _ = writeln!(w, "## Manufactured solutions (§1)\n");
    let _ = writeln!(
        w,
        "Unit cube, E = 1e6 Pa, ν = 0.3, Dirichlet data u = u_exact on the whole boundary (nodal backends \
         interpolate it at boundary nodes; weak backends integrate it in their boundary terms). Errors are \
         relative, with a Gauss rule exact to degree 6 per element; rates are log(e_coarse/e_fine)/log 2 \
         between consecutive rows.\n"
    );
    let _ = writeln!(w, "{header}");
    for problem in [Problem::MmsSin111, Problem::MmsCos123] {
        let groups = by_method(rows, problem);
        if groups.is_empty() {
            continue;
        }
        let _ = writeln!(w, "### `{}`\n", problem.key());
        let _ = writeln!(
            w,
            "| method | n | DOFs | elements | nnz | L2 error | L2 rate | H1 error | H1 rate | setup [s] | assemble [s] | solve [s] | total [s] | reps | peak RSS [MB] |"
        );
        let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        for (method, g) in &groups {
            let l2 = observed_rates(g, |r| r.l2_rel_error);
            let h1 = observed_rates(g, |r| r.h1_rel_error);
            for (i, r) in g.iter().enumerate() {
                let _ = writeln!(
                    w,
                    "| {method} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    r.n,
                    r.dofs,
                    r.elements,
                    r.nnz.map_or("—".into(), |v| v.to_string()),
                    sci(r.l2_rel_error),
                    rate(l2[i]),
                    sci(r.h1_rel_error),
                    rate(h1[i]),
                    static_timing_cells(r)
                );
            }
        }
        let _ = writeln!(w);
    }
    let _ = writeln!(w, "![relative error against run time](error_vs_time.svg)\n");
    let _ = writeln!(w, "![relative error against DOFs](error_vs_dofs.svg)\n");

    let reference = reference_of(rows);
    let cantilever = by_method(rows, Problem::Cantilever);
    if !cantilever.is_empty() {
        let _ = writeln!(w, "## Static cantilever (§2)\n");
        let _ = writeln!(
            w,
            "Beam [0,4]×[0,1]×[0,1] as 4n × n × n cells, clamped at x = 0, body force (0, 0, −ρg), E = 1e6 Pa, \
             ν = 0.3, ρ = 1000 kg/m³, linear (unwarped) static solve. `tip_uz_avg` is the mean of u_z over the \
             face x = 4 (2×2 Gauss points per cell face, evaluated by embedding), `tip_uz_point` is u_z at \
             (4, 0.5, 0.5), the strain energy is ½ fᵀu.\n"
        );
        match &reference {
            Some(r) => {
                let _ = writeln!(
                    w,
                    "**Reference.** The clamped edges make every method converge like h^(2λ) with λ = 0.711 at \
                     ν = 0.3 (benchmarks.md §2). For each method, Richardson extrapolation with that known rate \
                     from its two finest runs, u_lim = u_f + (u_f − u_c)/(2^(2λ) − 1), estimates its limit, with \
                     the size of that correction as its estimated error. Only consistent methods may make the \
                     reference, and only those whose limits agree with each other within the sum of their \
                     estimated errors (a method's own limit is not a reference for itself): **{}** agree on \
                     **tip_uz_avg = {:.5} m ± {:.5} m** ({:.3}%): their limits averaged with weights \
                     1/error², and as uncertainty the larger of that mean's own error and the largest \
                     distance from it of the members that pin it down (weight at least a tenth of the \
                     largest). Every other method is \
                     flagged below when its limit lies outside that band by more than its own estimated \
                     error. Tip errors are |u − u_ref| / |u_ref|; their rates should approach 2λ = 1.42 for the \
                     methods that converge to the reference.\n",
                    r.agreeing.join(", "),
                    r.value,
                    r.uncertainty,
                    100.0 * r.uncertainty / r.value.abs()
                );
                limits_table(w, r, "m");
            }
            None => {
                let _ =
                    writeln!(w, "No consistent method has two levels yet, so there is no extrapolated reference.\n");
            }
        }
        let _ = writeln!(
            w,
            "*Matrix-free to accuracy*: the same system solved again without assembling it, by CG on the \
             backend's stiffness action preconditioned by block Jacobi and the backend's coarse space (the \
             integrator's two-level preconditioner without the mass term; backends without a coarse space \
             show —), from nothing (build, preconditioner, iterations) to the first CG tolerance of \
             1e-1 … 1e-8 whose tip differs from the direct solve's by at most 1 % of that solve's tip \
             error: the time to the direct solve's accuracy, beside its *total*.\n"
        );
        let _ = writeln!(w, "{header}");
        let _ = writeln!(
            w,
            "| method | n | DOFs | elements | tip_uz_avg [m] | tip_uz_point [m] | strain energy [J] | tip error | rate | matrix-free to accuracy [s] | setup [s] | assemble [s] | solve [s] | total [s] | reps | peak RSS [MB] |"
        );
        let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        for (method, g) in &cantilever {
            let errors: Vec<Option<f64>> =
                g.iter().map(|r| reference.as_ref().and_then(|rf| tip_error(r, rf))).collect();
            let rates = observed_rates(g, |r| reference.as_ref().and_then(|rf| tip_error(r, rf)));
            for (i, r) in g.iter().enumerate() {
                let _ = writeln!(
                    w,
                    "| {method} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    r.n,
                    r.dofs,
                    r.elements,
                    fixed(r.tip_uz_avg, 6),
                    fixed(r.tip_uz_point, 6),
                    sci(r.strain_energy),
                    sci(errors[i]),
                    rate(rates[i]),
                    reference.as_ref().and_then(|rf| time_to_accuracy(r, rf.value)).map_or("—".to_string(), |p| {
                        format!("{:.3e} ({} its at {:.0e})", p.seconds, p.iterations, p.tolerance)
                    }),
                    static_timing_cells(r)
                );
            }
        }
        let _ = writeln!(w);
    }

    let dynamic = by_method(rows, Problem::Dynamic);
    if !dynamic.is_empty() {
        let _ = writeln!(w, "## Dynamic beam (§3)\n");
        let _ = writeln!(
            w,
            "The same beam with E = 1e8 Pa, ν = 0.3, ρ = 1000 kg/m³, Rayleigh β = 0.01 s, clamped, released \
             from rest under gravity: {DYNAMIC_STEPS} corotated linearly implicit Euler steps of 1/60 s with \
             each backend's time-stepping solver (Cholesky for voxel). Tip values are at t = 2 s; *Δ finest* is \
             the difference to the same method's finest level (no exact solution). *vs static* is the \
             self-consistency check: the final tip against the same method's static cantilever deflection on \
             the same mesh scaled by E_static/E_dynamic = 1e-2 (the run has settled by 2 s, and corotation \
             changes a 1 % deflection by far less than 1 %): a defect in the corotated forces shows here by \
             itself. Per-step times are the \
             integrator's phases divided by the steps; *setup* builds the discretization and the integrator \
             (pattern, symbolic factorization).\n"
        );
        let _ = writeln!(w, "{header}");
        let _ = writeln!(
            w,
            "| method | n | DOFs | nnz | tip_uz_avg(2 s) [m] | tip_uz_point(2 s) [m] | Δ finest [m] | vs static | setup [s] | rotations [ms/step] | assembly [ms/step] | solve [ms/step] | total [ms/step] | reps | peak RSS [MB] |"
        );
        let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        for (method, g) in &dynamic {
            let finest = g.last().and_then(|r| r.tip_uz_avg);
            for r in g {
                let steps = r.steps.unwrap_or(DYNAMIC_STEPS) as f64;
                let per_step = |s: Option<f64>| fixed(s.map(|s| 1e3 * s / steps), 3);
                let total_steps = match (r.seconds_total, r.seconds_setup) {
                    (Some(t), Some(s)) => Some(t - s),
                    _ => None,
                };
                let _ = writeln!(
                    w,
                    "| {method} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    r.n,
                    r.dofs,
                    r.nnz.map_or("—".into(), |v| v.to_string()),
                    fixed(r.tip_uz_avg, 6),
                    fixed(r.tip_uz_point, 6),
                    sci(r.tip_uz_avg.zip(finest).map(|(a, b)| (a - b).abs())),
                    self_consistency(r, rows).map_or("—".into(), |e| format!("{:+.3} %", 100.0 * e)),
                    sci(r.seconds_setup),
                    per_step(r.seconds_rotations),
                    per_step(r.seconds_assemble),
                    per_step(r.seconds_solve),
                    per_step(total_steps),
                    r.repetitions,
                    mb(r.peak_rss_mb)
                );
            }
        }
        let _ = writeln!(w);
    }
    let _ = writeln!(w, "![time per phase at each method's finest level](phases.svg)\n");
    cut_cantilever_section(w, rows, &header, &provenance.cut_load);

    let _ = writeln!(w, "## kaufmann2008 Table 1\n");
    let _ = writeln!(
        w,
        "Integration (building the discretization: element and face integrals), assembly (the matrix values: \
         element and face blocks written at precomputed positions, and the load) and solve (numeric Cholesky \
         factorization and solve) on a 10×10×10 grid of the unit cube, clamped at x = 0 under gravity, in ms. \
         Our sparsity pattern, fill-reducing order and symbolic factorization are built once per mesh and \
         reused by every time step; they get their own column *pattern + symbolic*, and *speed-up* counts \
         them (it is the paper's total over ours: integration + pattern + assembly + solve). The paper chose η \
         by hand; our IP build also searches η by doubling until the matrix is positive definite (one Cholesky \
         attempt per η), reported in its own column *η search* and not in *integration* (BZ is positive \
         definite for any η, so its search is one assembly of the blocks). *Sparsity* is the fraction of \
         stored entries of the assembled matrix: ours keeps full 3×3 node blocks, so BZ, whose penalty couples \
         neighbours component by component, stores the same pattern as IP, while the paper's 0.28% counts only \
         BZ's nonzeros. The paper's column was measured on a Core2 Duo 2.4 GHz; ours are medians of 3 runs on \
         the machine named above (`cleave_testkit::compare::table1_timings`), each method's row from the last \
         invocation that timed it (`--problem table1` or `all`; [`table1.csv`](table1.csv)).\n"
    );
    let _ = writeln!(
        w,
        "| method | paper: sparsity | integration | assembly | solve | ours: sparsity | integration | pattern + symbolic | assembly | solve | η search | DOFs | factor nnz | speed-up |"
    );
    let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let ours =
        |backend: &str, variant: &str| table1.iter().find(|(b, v, _)| b == backend && v == variant).map(|(_, _, t)| t);
    let cells = |t: Option<&Result<Table1Timings, String>>, paper_total: Option<f64>| match t {
        Some(Ok(t)) => {
            let ours_total = 1e3 * (t.integration + t.pattern + t.assembly + t.solve);
            let speedup = paper_total.map_or("—".to_string(), |p| format!("{:.1}×", p / ours_total));
            format!(
                "{:.2}% | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.2}M | {speedup}",
                100.0 * t.nnz as f64 / (t.dofs as f64 * t.dofs as f64),
                1e3 * t.integration,
                1e3 * t.pattern,
                1e3 * t.assembly,
                1e3 * t.solve,
                1e3 * t.search,
                t.dofs,
                t.factor_nnz as f64 / 1e6
            )
        }
        Some(Err(e)) => format!("failed: {} | | | | | | | | ", e.replace('|', "/")),
        None => "not timed yet | | | | | | | | ".into(),
    };
    for (label, backend, variant, sparsity, [i, a, s]) in KAUFMANN2008_TABLE1 {
        let _ = writeln!(
            w,
            "| {label} ({backend}/{variant}) | {sparsity:.2}% | {i:.0} | {a:.0} | {s:.0} | {} |",
            cells(ours(backend, variant), Some(i + a + s))
        );
    }
    for (backend, variant, t) in table1 {
        if !KAUFMANN2008_TABLE1.iter().any(|(_, b, v, _, _)| b == backend && v == variant) {
            let _ =
                writeln!(w, "| {backend}/{variant} (not in the paper) | — | — | — | — | {} |", cells(Some(t), None));
        }
    }
    let _ = writeln!(w);
    let _ = write!(w, "{cut_section}");
    let _ = writeln!(w, "## How each study stopped\n");
    for s in stops {
        let _ = writeln!(w, "- {s}");
    }
    md
}

/// The table of each method's extrapolated limit and how it relates to `reference`.
fn limits_table(w: &mut String, reference: &TipReference, unit: &str) {
    let _ = writeln!(
        w,
        "| method | consistent | levels | values [{unit}] | limit [{unit}] | estimated error [{unit}] | verdict |"
    );
    let _ = writeln!(w, "|---|---|---|---|---|---|---|");
    for l in &reference.limits {
        let verdict = if reference.agreeing.contains(&l.method) {
            "makes the reference".to_string()
        } else {
            match reference.different_limit(l) {
                Some(away) => format!("**converges to a different limit, {:.1} % away**", 100.0 * away),
                None => "agrees within its estimated error".to_string(),
            }
        };
        let _ = writeln!(
            w,
            "| {} | {} | {}, {} | {:.6}, {:.6} | {:.5} | {:.1e} | {verdict} |",
            l.method,
            if l.consistent { "yes" } else { "no" },
            l.levels.0,
            l.levels.1,
            l.values.0,
            l.values.1,
            l.limit,
            l.estimated_error
        );
    }
    let _ = writeln!(w);
}

/// The three references of the cut cantilever: tip, strain energy, crack opening.
pub fn cut_references(rows: &[Row]) -> [(&'static str, &'static str, Option<TipReference>); 3] {
    [
        ("tip_uz_avg", "m", cut_cantilever_reference(rows, |r| r.tip_uz_avg, &method_is_consistent)),
        ("strain energy", "J", cut_cantilever_reference(rows, |r| r.strain_energy, &method_is_consistent)),
        ("crack opening", "m", cut_cantilever_reference(rows, |r| r.crack_opening, &method_is_consistent)),
    ]
}

/// The "Cut cantilever (§5)" section: references, per-level table, the dynamic cut.
/// `load`: the line on the load the timings ran under (or where they came from).
fn cut_cantilever_section(w: &mut String, rows: &[Row], header: &str, load: &str) {
    let statics = by_method(rows, Problem::CutCantilever);
    let dynamic = by_method(rows, Problem::CutDynamic);
    if statics.is_empty() && dynamic.is_empty() {
        return;
    }
    let _ = writeln!(w, "## Cut cantilever (§5)\n");
    let _ = writeln!(
        w,
        "The static cantilever of §2 (E = 1e6 Pa, ν = 0.3, linear) with a zero-thickness crack: the plane x = 2 \
         through the whole width, from the top face z = 1 down to z = 0.5, given to every method that cuts as \
         the same soup of two triangles in rest space (`cleave_testkit::problems::crack::cantilever`, \
         overhanging the beam by one cell on the open sides) and applied to its uncut box with its own cutting \
         (`CompareBackend::build_cut_box`): **virtualnode/linear-tet** by `Cuttable::cut` (the generalized \
         virtual node algorithm; x = 2 is a node plane of its BCC lattice, and so is z = 0.5 for even n); \
         **voxel/trilinear** by `Cuttable::cut`, which separates the cubes across every face whose dual edge \
         (centre to centre) the soup crosses (the conforming 4n × n × n hexahedral grid of §5 whose nodes on \
         {{x = 2, z > 0.5}} are duplicated for the cubes right of the plane, counted in the tests). Levels \
         start at n = 2 and are even (for odd n the front z = 0.5 runs through the centres of a row of cube \
         faces, which the closed crack takes). The crack \
         opening is u_x(2⁺, 0.5, 1) − u_x(2⁻, 0.5, 1), each side evaluated by embedding 1e-4 h from the plane. \
         Registered methods that cannot cut do not run it.\n"
    );
    let references = cut_references(rows);
    let _ = writeln!(
        w,
        "**Reference.** The crack front is a singularity stronger than the clamped edges (λ = 1/2): tip, \
         energy and opening converge like h¹, so each method's limit is Richardson extrapolation with rate 1 \
         from its two finest levels, u_lim = u_f + (u_f − u_c)/(2 − 1) = 2u_f − u_c, and the size of that \
         correction is its estimated error; the reference is then formed by the rule of §2 (only consistent \
         methods whose limits agree within the sum of their estimated errors, weighted by 1/error²). The two \
         cutting methods are independent discretizations (trilinear cubes, linear tetrahedra on a BCC \
         lattice), so when both make a reference it is not either method's own limit.\n"
    );
    for (name, unit, reference) in &references {
        match reference {
            Some(r) => {
                let _ = writeln!(
                    w,
                    "- **{name} = {:.5} {unit} ± {:.5} {unit}** ({:.2} %), made by {}; spread of their limits: {}.",
                    r.value,
                    r.uncertainty,
                    100.0 * r.uncertainty / r.value.abs(),
                    r.agreeing.join(", "),
                    spread(r, unit)
                );
            }
            None => {
                let _ = writeln!(w, "- {name}: no consistent method has two levels yet.");
            }
        }
    }
    let _ = writeln!(w);
    for (name, unit, reference) in &references {
        if let Some(r) = reference {
            let _ = writeln!(w, "Limits of {name}:\n");
            limits_table(w, r, unit);
        }
    }
    let tip_reference = references[0].2.as_ref();
    if !statics.is_empty() {
        let _ = writeln!(w, "{header}");
        let _ = writeln!(w, "{load}\n");
        let _ = writeln!(
            w,
            "| method | n | DOFs | elements | tip_uz_avg [m] | strain energy [J] | crack opening [m] | tip error | rate | setup [s] | assemble [s] | solve [s] | total [s] | reps | peak RSS [MB] |"
        );
        let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        for (method, g) in &statics {
            let error = |r: &Row| tip_reference.and_then(|rf| tip_error(r, rf));
            let rates = observed_rates(g, error);
            for (i, r) in g.iter().enumerate() {
                let _ = writeln!(
                    w,
                    "| {method} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    r.n,
                    r.dofs,
                    r.elements,
                    fixed(r.tip_uz_avg, 6),
                    sci(r.strain_energy),
                    fixed(r.crack_opening, 6),
                    sci(error(r)),
                    rate(rates[i]),
                    static_timing_cells(r)
                );
            }
        }
        let _ = writeln!(w);
        cost_of_cutting(w, rows, &statics, tip_reference);
        let _ = writeln!(
            w,
            "![cut cantilever: tip error against run time, beside the uncut cantilever](error_vs_time.svg)\n"
        );
    }
    if !dynamic.is_empty() {
        let _ = writeln!(w, "### Dynamic cut\n");
        let _ = writeln!(
            w,
            "The dynamic beam of §3 (E = 1e8 Pa, ν = 0.3, ρ = 1000 kg/m³, Rayleigh β = 0.01 s, h = 1/60 s, \
             clamped, released from rest under gravity) cut by the same crack after {CUT_DYNAMIC_CUT_STEP} steps \
             (t = 1 s) and run to {CUT_DYNAMIC_STEPS} steps (t = 4 s). The cut happens between steps as \
             `cleave_scene::Simulation` does it: the backend's cut box and its topology change go to \
             `Integrator::apply_topology_change` (x and v carried by the gather of duplicated nodes, rotations \
             as warm starts) with the Dirichlet data resolved again on the cut mesh; the harness first checks \
             that the cut box's rest positions are the running box's gathered. Energies are totals: kinetic + \
             elastic + gravitational, the last −fᵀu = −fᵀ(x − X₀) from the rest shape with the gravity load f \
             of the current mesh (the integrator's −fᵀx plus the datum fᵀX₀). *E after − before* must not be \
             positive beyond rounding (a cut must not add energy; the sums over all nodes round at about 1e-13 \
             of abs(E)); *max after* is the largest total of any later step over \
             the energy before the cut. p = Σ m v with the lumped masses. *vs static cut* is the tip at 4 s \
             against the same method's static cracked deflection on the same mesh scaled by E_static/E_dynamic \
             = 1e-2 (it must settle within 1 %).\n"
        );
        let _ = writeln!(
            w,
            "| method | n | DOFs | E before cut [J] | E after − before [J] | relative | max after − before [J] | \
             abs(p) before [kg m/s] | abs(Δp) [kg m/s] | tip_uz_avg(4 s) [m] | crack opening(4 s) [m] | vs static cut | total [s] |"
        );
        let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|---|---|");
        for (method, g) in &dynamic {
            for r in g {
                let delta = r.energy_after_cut.zip(r.energy_before_cut).map(|(a, b)| a - b);
                let relative = delta.zip(r.energy_before_cut).map(|(d, b)| d / b.abs());
                let max_rise = r.energy_max_after_cut.zip(r.energy_before_cut).map(|(a, b)| a - b);
                let _ = writeln!(
                    w,
                    "| {method} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                    r.n,
                    r.dofs,
                    sci(r.energy_before_cut),
                    sci(delta),
                    sci(relative),
                    sci(max_rise),
                    sci(r.momentum_before_cut),
                    sci(r.momentum_change),
                    fixed(r.tip_uz_avg, 6),
                    fixed(r.crack_opening, 6),
                    self_consistency(r, rows).map_or("—".into(), |e| format!("{:+.3} %", 100.0 * e)),
                    sci(r.seconds_total)
                );
            }
        }
        let _ = writeln!(w);
    }
}

/// What cutting costs in accuracy, per method: at its finest level with both a cut and an uncut
/// cantilever row, the two tip errors (each against its own problem's reference) and their
/// ratio, and the observed rates into that level.
fn cost_of_cutting(w: &mut String, rows: &[Row], statics: &[(String, Vec<&Row>)], cut: Option<&TipReference>) {
    let (Some(cut), Some(uncut)) = (cut, reference_of(rows)) else { return };
    let uncut_rows = by_method(rows, Problem::Cantilever);
    let mut lines = Vec::new();
    for (method, g) in statics {
        let Some(plain) = uncut_rows.iter().find(|(m, _)| m == method).map(|(_, g)| g) else { continue };
        let Some((c, u)) = g.iter().rev().find_map(|c| plain.iter().find(|u| u.n == c.n).map(|u| (*c, *u))) else {
            continue;
        };
        let (Some(ec), Some(eu)) = (tip_error(c, cut), tip_error(u, &uncut)) else { continue };
        let rate_into = |g: &[&Row], rf: &TipReference| {
            let upto: Vec<&Row> = g.iter().copied().filter(|r| r.n <= c.n).collect();
            observed_rates(&upto, |r| tip_error(r, rf)).last().copied().flatten()
        };
        lines.push(format!(
            "- {method}, n = {}: tip error {ec:.2e} cut, {eu:.2e} uncut ({:.1}×); observed rate into n = {}: {} cut, {} uncut.",
            c.n,
            ec / eu,
            c.n,
            rate(rate_into(g, cut)),
            rate(rate_into(plain, &uncut))
        ));
    }
    if !lines.is_empty() {
        let _ = writeln!(
            w,
            "**What the cut costs in accuracy** (same method, same n, each problem against its own reference):\n"
        );
        for l in lines {
            let _ = writeln!(w, "{l}");
        }
        let _ = writeln!(w);
    }
}

/// The largest distance between the limits of a reference's members, in absolute and relative
/// terms.
fn spread(reference: &TipReference, unit: &str) -> String {
    let members: Vec<f64> =
        reference.limits.iter().filter(|l| reference.agreeing.contains(&l.method)).map(|l| l.limit).collect();
    let (lo, hi) = members.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    if members.len() < 2 {
        return "one method only".into();
    }
    format!("{:.5} {unit} ({:.2} %)", hi - lo, 100.0 * (hi - lo) / reference.value.abs())
}

/// The timing tail shared by the static tables: setup, assemble, solve, total [s], reps, peak RSS.
fn static_timing_cells(r: &Row) -> String {
    format!(
        "{} | {} | {} | {} | {} | {}",
        sci(r.seconds_setup),
        sci(r.seconds_assemble),
        sci(r.seconds_solve),
        sci(r.seconds_total),
        r.repetitions,
        mb(r.peak_rss_mb)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table1_rows_round_trip_and_failures_keep_their_message() {
        let ok: Table1Row = (
            "dg".into(),
            "ip-2".into(),
            Ok(Table1Timings {
                integration: 0.25,
                assembly: 0.125,
                pattern: 0.5,
                solve: 3.0,
                search: 4.5,
                dofs: 30000,
                nnz: 5_760_000,
                factor_nnz: 38_203_200,
            }),
        );
        let failed: Table1Row = ("voxel".into(), "trilinear".into(), Err("solve failed: pivot 3, not positive".into()));
        assert_eq!(table1_from_csv(&table1_to_csv(&ok)), Some(ok));
        let back = table1_from_csv(&table1_to_csv(&failed)).unwrap();
        assert_eq!(back.2, Err("solve failed: pivot 3; not positive".to_string()));
        assert_eq!(table1_to_csv(&failed).split(',').count(), TABLE1_HEADER.split(',').count());
    }

    #[test]
    fn stop_lines_are_read_back_with_their_method_and_problem() {
        let dir = std::env::temp_dir().join(format!("cleave-stops-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("compare.md");
        fs::write(
            &path,
            "# x\n\n## How each study stopped\n\n- voxel/trilinear cantilever: 5 levels, stopped by budget: n = 32\n- dg/ip-2 mms-sin111: 4 levels, stopped by level cap n ≤ 8\n\n## Later\n\n- not/a stop: line\n",
        )
        .unwrap();
        let stops = previous_stops(&path);
        fs::remove_dir_all(&dir).unwrap();
        let keys: Vec<(&str, &str)> = stops.iter().map(|(m, p, _)| (m.as_str(), p.as_str())).collect();
        assert_eq!(keys, vec![("voxel/trilinear", "cantilever"), ("dg/ip-2", "mms-sin111")]);
        assert_eq!(stops[0].2, "voxel/trilinear cantilever: 5 levels, stopped by budget: n = 32");
    }

    #[test]
    fn problem_names_select_studies_table1_and_cutting() {
        let s = selection(&["cutting".into(), "mms".into()]).unwrap();
        assert_eq!(s.problems, vec![Problem::MmsSin111, Problem::MmsCos123]);
        assert!(s.cutting && !s.table1);
        let all = selection(&["all".into()]).unwrap();
        assert_eq!(all.problems, Problem::ALL.to_vec());
        assert!(all.cutting && all.table1);
        assert!(selection(&["cuts".into()]).is_err());
        let cut = selection(&["cut-cantilever".into()]).unwrap();
        assert_eq!(cut.problems, vec![Problem::CutCantilever, Problem::CutDynamic]);
        assert!(!cut.cutting && !cut.table1);
    }
}

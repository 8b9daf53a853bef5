//! `cargo xtask tidy`: the invariants of docs/architecture.md that the compiler does not check
//! (which crate may depend on which, no terminal or file I/O in library code, a `//!` line at
//! the top of every source file), checked over the workspace's files. A test runs it, so
//! `cargo test --workspace` (and CI) fails on a violation.

use std::fs;
use std::path::{Path, PathBuf};

/// The cleave crates each crate may depend on (normal dependencies; dev-dependencies are free).
/// A crate under `crates/` that is not listed is itself a violation: classify it here.
const LAYERS: &[(&str, &[&str])] = &[
    ("cleave-core", &[]),
    ("cleave-geometry", &["cleave-core"]),
    // Backends: the core and shared geometry only, never each other or the integrator.
    ("cleave-voxel", BACKEND_DEPENDENCIES),
    ("cleave-dg", BACKEND_DEPENDENCIES),
    ("cleave-virtualnode", BACKEND_DEPENDENCIES),
    ("cleave-meanvalue", BACKEND_DEPENDENCIES),
    // Contact finds what touches; it neither steps nor knows a backend.
    ("cleave-contact", &["cleave-core", "cleave-geometry"]),
    // The integrator never knows which backend it drives.
    ("cleave-integrator", &["cleave-core", "cleave-geometry", "cleave-contact"]),
    // Rigid fragments on rapier: the hand-off, beside the integrator, driven by the scene runner.
    ("cleave-rigid", &["cleave-core"]),
    // Checks every backend must pass, written against the traits.
    ("cleave-testkit", &["cleave-core", "cleave-geometry", "cleave-integrator"]),
    // The one place backends are named.
    (
        "cleave-registry",
        &[
            "cleave-core",
            "cleave-geometry",
            "cleave-integrator",
            "cleave-testkit",
            "cleave-voxel",
            "cleave-dg",
            "cleave-virtualnode",
            "cleave-meanvalue",
        ],
    ),
    // Scenes reach backends through the registry only.
    ("cleave-scene", &["cleave-core", "cleave-geometry", "cleave-integrator", "cleave-registry", "cleave-rigid"]),
];

const BACKEND_DEPENDENCIES: &[&str] = &["cleave-core", "cleave-geometry"];

/// Library crates whose non-test code may write to the terminal: the testkit's assertion
/// helpers print the table of checks they ran for `cargo test -- --nocapture`.
const TERMINAL_ALLOWED: &[&str] = &["cleave-testkit"];

/// The only library crate that opens files (geometry parses from readers).
const FILES_ALLOWED: &[&str] = &["cleave-scene"];

/// Every violation in the workspace at `root`, one line each, naming the file.
pub fn check(root: &Path) -> Vec<String> {
    let mut violations = Vec::new();
    let crates_dir = root.join("crates");
    let mut crate_dirs: Vec<PathBuf> = match fs::read_dir(&crates_dir) {
        Ok(entries) => {
            entries.filter_map(Result::ok).map(|e| e.path()).filter(|p| p.join("Cargo.toml").is_file()).collect()
        }
        Err(e) => return vec![format!("{}: {e}", crates_dir.display())],
    };
    crate_dirs.sort();
    for dir in &crate_dirs {
        let manifest = dir.join("Cargo.toml");
        let name = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        match fs::read_to_string(&manifest) {
            Ok(text) => violations.extend(check_manifest(&name, &manifest, &text)),
            Err(e) => violations.push(format!("{}: {e}", manifest.display())),
        }
        for file in rust_files(&dir.join("src")) {
            match fs::read_to_string(&file) {
                Ok(text) => violations.extend(check_library_source(&name, &file, &text)),
                Err(e) => violations.push(format!("{}: {e}", file.display())),
            }
        }
    }
    for top in ["crates", "xtask", "benches"] {
        for file in rust_files(&root.join(top)) {
            match fs::read_to_string(&file) {
                Ok(text) => violations.extend(check_header(&file, &text)),
                Err(e) => violations.push(format!("{}: {e}", file.display())),
            }
        }
    }
    violations
}

/// The `.rs` files under `dir`, recursively, sorted (none when it does not exist); build output
/// (`target`) is skipped.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = fs::read_dir(&d) else { continue };
        for entry in entries.filter_map(Result::ok) {
            let path = entry.path();
            if path.is_dir() {
                if path.file_name().is_some_and(|n| n != "target") {
                    stack.push(path);
                }
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// Violations of the dependency layers in crate `name`'s manifest `text`.
pub fn check_manifest(name: &str, path: &Path, text: &str) -> Vec<String> {
    let Some(&(_, allowed)) = LAYERS.iter().find(|(crate_name, _)| *crate_name == name) else {
        return vec![format!(
            "{}: crate {name} has no layer in xtask/src/tidy.rs (LAYERS): say which cleave crates it may depend on",
            path.display()
        )];
    };
    let mut violations = Vec::new();
    let mut in_dependencies = false;
    for (number, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.starts_with('[') {
            // `[dependencies]` and `[target.'cfg(..)'.dependencies]`, not dev- or build-dependencies.
            let section = line.trim_matches(|c| c == '[' || c == ']');
            in_dependencies = section == "dependencies" || section.ends_with(".dependencies");
            continue;
        }
        if !in_dependencies {
            continue;
        }
        let dependency: String =
            line.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '-' || *c == '_').collect();
        if dependency.starts_with("cleave-") && !allowed.contains(&dependency.as_str()) {
            violations.push(format!(
                "{}:{}: {name} depends on {dependency}, outside its layer (allowed: {})",
                path.display(),
                number + 1,
                if allowed.is_empty() { "no cleave crate".to_string() } else { allowed.join(", ") }
            ));
        }
    }
    violations
}

/// Terminal and file I/O in the non-test code of library crate `name` (the lines before its
/// first `#[cfg(test)]`, none in a file that opens with `#![cfg(test)]`; comments skipped).
pub fn check_library_source(name: &str, path: &Path, text: &str) -> Vec<String> {
    const TERMINAL: &[&str] = &["println!", "eprintln!", "print!(", "eprint!(", "dbg!(", "io::stdout", "io::stderr"];
    const FILES: &[&str] = &["std::fs", "fs::read", "fs::write", "File::open", "File::create"];
    let mut violations = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let code = line.trim_start();
        if code.starts_with("#[cfg(test)]") || code.starts_with("#![cfg(test)]") {
            break;
        }
        if code.starts_with("//") {
            continue;
        }
        let code = code.split("//").next().unwrap_or(code);
        let mut flag = |patterns: &[&str], allowed: &[&str], what: &str| {
            if allowed.contains(&name) {
                return;
            }
            if let Some(found) = patterns.iter().find(|p| code.contains(*p)) {
                violations.push(format!("{}:{}: {what} in library crate {name} ({found})", path.display(), number + 1));
            }
        };
        flag(TERMINAL, TERMINAL_ALLOWED, "terminal output");
        flag(FILES, FILES_ALLOWED, "file access");
    }
    violations
}

/// A source file must open with a `//!` line saying what it holds.
pub fn check_header(path: &Path, text: &str) -> Vec<String> {
    match text.lines().next() {
        Some(first) if first.starts_with("//!") => Vec::new(),
        _ => vec![format!("{}:1: the file does not open with a `//!` line saying what it holds", path.display())],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_keeps_the_invariants_of_its_architecture() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let violations = check(&root);
        assert!(violations.is_empty(), "tidy found {} violations:\n{}", violations.len(), violations.join("\n"));
    }

    #[test]
    fn tidy_finds_what_it_is_meant_to_find() {
        let manifest = Path::new("crates/cleave-voxel/Cargo.toml");
        let text = "[package]\nname = \"cleave-voxel\"\n[dependencies]\ncleave-core.workspace = true\ncleave-dg = { path = \"../cleave-dg\" }\n[dev-dependencies]\ncleave-integrator.workspace = true\n";
        let found = check_manifest("cleave-voxel", manifest, text);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].contains(":5:") && found[0].contains("cleave-dg"), "{found:?}");
        assert_eq!(check_manifest("cleave-new", manifest, "").len(), 1, "an unclassified crate is a violation");

        let source = Path::new("crates/cleave-dg/src/lib.rs");
        let text = "//! DG.\n// println!(\"commented\")\nfn f() { eprintln!(\"x\"); }\nfn g() { let _ = std::fs::read(\"a\"); }\n#[cfg(test)]\nmod tests { fn t() { println!(\"ok in tests\"); } }\n";
        let test_module = "//! Tests of DG.\n#![cfg(test)]\nfn t() { println!(\"ok in tests\"); }\n";
        assert!(check_library_source("cleave-dg", source, test_module).is_empty());
        let found = check_library_source("cleave-dg", source, text);
        assert_eq!(found.len(), 2, "{found:?}");
        assert!(found[0].contains(":3: terminal output") && found[1].contains(":4: file access"), "{found:?}");
        assert!(check_library_source("cleave-scene", source, "fn g() { std::fs::read(\"a\"); }").is_empty());

        assert!(check_header(source, "//! What it holds.\n").is_empty());
        assert_eq!(check_header(source, "// not a doc line\n").len(), 1);
        assert_eq!(check_header(source, "").len(), 1);
    }
}

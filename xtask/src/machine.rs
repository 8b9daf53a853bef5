//! What the report says about the machine (cores, CPU model) and the per-run peak resident
//! memory, read from Linux's /proc (absent elsewhere: the cells stay empty).

use std::fs;
use std::process::Command;

/// "N cores (available_parallelism), CPU: model", the line written above every table.
pub fn machine_line() -> String {
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let model = cpu_model().unwrap_or_else(|| "unknown model".into());
    format!("Machine: {cores} cores (`std::thread::available_parallelism`), CPU: {model} (lscpu).")
}

/// The load averages of /proc/loadavg against the core count, for reports whose timings may have
/// shared the cores with other processes; empty where /proc is absent.
pub fn load_line() -> String {
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let Some(loads) = fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|text| text.split_whitespace().take(3).filter_map(|v| v.parse::<f64>().ok()).collect::<Vec<f64>>())
    else {
        return String::new();
    };
    let [one, five, fifteen] = loads[..] else { return String::new() };
    let shared = if five > cores as f64 {
        "above the core count: other processes shared the cores, so these timings are inflated and noisy"
    } else {
        "within the core count"
    };
    format!(
        "Load average when this section was written: {one:.2} (1 min), {five:.2} (5 min), {fifteen:.2} (15 min) on {cores} cores, {shared}."
    )
}

fn cpu_model() -> Option<String> {
    let from_lscpu = Command::new("lscpu").output().ok().and_then(|out| {
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .find_map(|l| l.strip_prefix("Model name:").map(|m| m.trim().to_string()))
    });
    from_lscpu.or_else(|| {
        fs::read_to_string("/proc/cpuinfo")
            .ok()?
            .lines()
            .find_map(|l| l.strip_prefix("model name").and_then(|m| m.split(':').nth(1)).map(|m| m.trim().to_string()))
    })
}

/// Peak resident set size since the last reset: `VmHWM` after writing 5 to `clear_refs`.
pub struct RssProbe {
    reset_ok: bool,
}

impl RssProbe {
    /// A probe (not yet reset).
    pub fn new() -> Self {
        Self { reset_ok: false }
    }

    /// Resets the kernel's high-water mark to the current RSS.
    pub fn reset(&mut self) {
        self.reset_ok = fs::write("/proc/self/clear_refs", "5").is_ok();
    }

    /// Peak RSS in MB since the reset; `None` when the reset or the read failed (a process-wide
    /// peak would be misleading).
    pub fn peak_mb(&self) -> Option<f64> {
        if !self.reset_ok {
            return None;
        }
        let status = fs::read_to_string("/proc/self/status").ok()?;
        let kb: f64 =
            status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?.trim().trim_end_matches("kB").trim().parse().ok()?;
        Some(kb / 1024.0)
    }
}

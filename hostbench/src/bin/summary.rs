//! Prints each measured figure beside the NeRFlex paper's.
//!
//! `cargo run -p nerflex-hostbench --bin summary [-- --criterion-dir DIR]`
//!
//! Reads criterion's `target/criterion/<bench>/new/estimates.json`. The
//! table below drives it: add a row per figure (benches of later issues:
//! shader, segmentation 3.8 s, profiler 0.277 s, …). Rows whose benchmark
//! has not been run print "not run".

use nerflex_hostbench::{criterion_dir, human_ns, read_estimate};
use std::path::PathBuf;

/// One figure.
struct Row {
    /// What is measured.
    what: &'static str,
    /// criterion's benchmark id (`group/function[/parameter]`).
    bench: &'static str,
    /// The paper's figure in seconds, if it reports one.
    paper_s: Option<f64>,
    /// How to run the benchmark.
    command: &'static str,
}

const ROWS: &[Row] = &[
    Row {
        what: "DP configuration selection, 5 objects × 45 configs, 240 MB in 0.1 MB units",
        bench: "mck/paper",
        paper_s: Some(1.87),
        command: "cargo bench -p nerflex-hostbench --bench mck",
    },
    Row {
        what: "  … 100 objects × 45 configs",
        bench: "mck_objects/100",
        paper_s: None,
        command: "cargo bench -p nerflex-hostbench --bench mck",
    },
    Row {
        what: "  … 5 objects × 100 configs",
        bench: "mck_configs/100",
        paper_s: None,
        command: "cargo bench -p nerflex-hostbench --bench mck",
    },
    Row {
        what: "  … 5 × 45, 10 KB units (24 000 units)",
        bench: "mck_unit_bytes/10000",
        paper_s: None,
        command: "cargo bench -p nerflex-hostbench --bench mck",
    },
];

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let mut dir = criterion_dir();
    while let Some(a) = args.next() {
        match a.as_str() {
            "--criterion-dir" => {
                dir = PathBuf::from(
                    args.next()
                        .ok_or_else(|| anyhow::anyhow!("--criterion-dir needs a folder"))?,
                )
            }
            "-h" | "--help" => {
                println!(
                    "usage: summary [--criterion-dir DIR]   (default {})",
                    dir.display()
                );
                return Ok(());
            }
            other => anyhow::bail!("unknown argument {other:?} (try --help)"),
        }
    }
    println!("criterion results from {}\n", dir.display());
    let width = ROWS
        .iter()
        .map(|r| r.what.chars().count())
        .max()
        .unwrap_or(0);
    println!(
        "{:<width$}  {:>10}  {:>18}  {:>10}",
        "figure", "paper", "nerflex", "speed-up"
    );
    let mut not_run = Vec::new();
    for r in ROWS {
        let paper = r
            .paper_s
            .map_or_else(|| "-".to_string(), |s| human_ns(s * 1e9));
        let (ours, ratio) = match read_estimate(&dir, r.bench)? {
            Some(e) => (
                format!(
                    "{} ±{:.0}%",
                    human_ns(e.ns),
                    50.0 * (e.high_ns - e.low_ns) / e.ns
                ),
                r.paper_s
                    .map_or_else(|| "-".to_string(), |s| format!("×{:.0}", s * 1e9 / e.ns)),
            ),
            None => {
                if !not_run.contains(&r.command) {
                    not_run.push(r.command);
                }
                ("not run".to_string(), "-".to_string())
            }
        };
        println!("{:<width$}  {paper:>10}  {ours:>18}  {ratio:>10}", r.what);
    }
    if !not_run.is_empty() {
        println!("\nto fill the \"not run\" rows:");
        for c in not_run {
            println!("  {c}");
        }
    }
    Ok(())
}

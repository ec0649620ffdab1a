//! `nerflex plan`: choose one (g, p, geometry) configuration per object
//! under a device's memory budget, and print the plan as a table or JSON
//! (both name each object's geometry).
//!
//! Infeasible plans exit non-zero with the error text (for `block` and
//! `single`, which always have a plan, after printing it with
//! `"feasible": false`).

use crate::baselines::{self, Budget, Method, Objective, Plan};
use crate::device::Device;
use crate::scene_file;
use crate::scene_file::Scene;
use anyhow::{bail, Context};
use nerflex_core::units::Bytes;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::PathBuf;

/// Flags of `nerflex plan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (JSON): objects with a configuration table or a profile.
    #[arg(long, value_name = "FILE")]
    pub scene: PathBuf,
    /// Device: a built-in name (iphone13, pixel4) or a device TOML file.
    #[arg(long, value_name = "NAME|FILE")]
    pub device: String,
    /// Selection method.
    #[arg(long, value_enum, default_value_t = Method::Dp)]
    pub method: Method,
    /// Memory budget in MB (10^6 bytes), instead of the device's.
    #[arg(long, value_name = "X", allow_negative_numbers = true)]
    pub budget_mb: Option<f64>,
    /// Planning unit in bytes: sizes are rounded up to it, the budget down
    /// [default: 0.1 MB, finer under 100 MB, coarser over 6.5 GB].
    #[arg(long, value_name = "N")]
    pub unit_bytes: Option<u64>,
    /// Plan against the budget less this share, in percent, so that a plan
    /// whose sizes the profiles under-predict by up to that share still
    /// fits once baked [default: 0]. The trained sweep's profiles
    /// under-predict by up to 11.3 % (docs/profiler.md, "A size margin").
    #[arg(long, value_name = "PCT", allow_negative_numbers = true)]
    pub size_margin: Option<f64>,
    /// What the selector maximises: `mean` (the paper's sum of predicted
    /// SSIM) or `area` (each object's SSIM weighted by 1 / zoom², its
    /// network's enlargement, read from `--segmentation`).
    #[arg(long, value_enum, default_value_t = Objective::Mean)]
    pub objective: Objective,
    /// A run's `segment/segmentation.json`, whose groups give each
    /// network's mean zoom (for `--objective area`).
    #[arg(long, value_name = "FILE")]
    pub segmentation: Option<PathBuf>,
    /// Print the plan as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The part of `segmentation.json` the area objective reads.
#[derive(serde::Deserialize)]
struct Zooms {
    groups: Vec<ZoomGroup>,
}

#[derive(serde::Deserialize)]
struct ZoomGroup {
    folder: String,
    mean_zoom: f64,
}

/// Each scene object's weight under `objective` (all 1 for `mean`); every
/// object must be a network of the segmentation for `area`.
fn weights(
    objective: Objective,
    segmentation: Option<&std::path::Path>,
    scene: &Scene,
) -> anyhow::Result<Vec<f64>> {
    let file = match (objective, segmentation) {
        (Objective::Mean, None) => return Ok(vec![1.0; scene.objects.len()]),
        (Objective::Mean, Some(_)) => {
            bail!("--segmentation: only read with --objective area")
        }
        (Objective::Area, None) => bail!(
            "--objective area needs --segmentation FILE (a run's segment/segmentation.json) for each network's zoom"
        ),
        (Objective::Area, Some(f)) => f,
    };
    let text =
        std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
    let z: Zooms = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a segmentation.json", file.display()))?;
    let zooms: Vec<(String, f64)> = z
        .groups
        .into_iter()
        .map(|g| (g.folder, g.mean_zoom))
        .collect();
    if let Some(o) = scene
        .objects
        .iter()
        .find(|o| !zooms.iter().any(|(n, _)| *n == o.name))
    {
        bail!(
            "{}: no network `{}` (the scene's objects must be its groups' folders)",
            file.display(),
            o.name
        );
    }
    objective
        .weights(scene, &zooms)
        .map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))
}

/// [`Budget::less_size_margin`], with an error naming the flag.
pub fn planning_budget(total: Bytes, margin_pct: f64) -> anyhow::Result<Bytes> {
    Budget::less_size_margin(total, margin_pct).with_context(|| {
        format!("--size-margin: must be a percentage from 0 up to (not including) 100, got {margin_pct}")
    })
}

/// Runs `nerflex plan`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let scene = scene_file::load(&args.scene)?;
    let device = Device::lookup(&args.device)?;
    let total = match args.budget_mb {
        None => device.budget(),
        Some(mb) => Bytes::from_mb(mb).map_err(|e| {
            anyhow::anyhow!("--budget-mb: must be a non-negative number of MB: {e}")
        })?,
    };
    let margin = args.size_margin.unwrap_or(0.0);
    let whole = total;
    let total = planning_budget(whole, margin)?;
    let budget = match args.unit_bytes {
        None => Budget::new(total),
        Some(0) => bail!("--unit-bytes: must be at least 1"),
        Some(u) => Budget::with_unit(total, Bytes(u)),
    };
    let weights = weights(args.objective, args.segmentation.as_deref(), &scene)?;
    let mut plan = baselines::plan_weighted(args.method, &scene, budget, &weights)
        .with_context(|| format!("{} plan for {}", args.method, args.scene.display()))?;
    plan.device = Some(device.name.clone());
    let text = if args.json {
        let mut v = json(&plan)?;
        if let Some(map) = v.as_object_mut() {
            // budget_bytes is what the plan was made against; say what it
            // came from.
            map.insert("size_margin_pct".into(), margin.into());
            map.insert("unreduced_budget_bytes".into(), whole.0.into());
            if args.objective != Objective::Mean {
                // The objects' qualities stay unweighted; say what was maximised.
                map.insert("objective".into(), args.objective.name().into());
            }
        }
        let mut s = serde_json::to_string_pretty(&v)?;
        s.push('\n');
        s
    } else {
        let mut t = String::new();
        if args.objective != Objective::Mean {
            let _ = writeln!(
                t,
                "objective {}: each object's SSIM weighted by 1 / zoom² (SSIM below unweighted)",
                args.objective
            );
        }
        if margin > 0.0 {
            let _ = writeln!(
                t,
                "size margin {margin} %: planned against {:.2} of {:.2} MB",
                total.as_mb(),
                whole.as_mb()
            );
        }
        t.push_str(&table(&plan, budget));
        t
    };
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .context("writing the plan to stdout")?;
    if !plan.feasible {
        bail!(
            "{} plan is infeasible: it needs {:.2} MB ({} bytes), over the budget of {:.2} MB ({} bytes)",
            plan.method,
            Bytes(plan.total_size_bytes).as_mb(),
            plan.total_size_bytes,
            Bytes(plan.budget_bytes).as_mb(),
            plan.budget_bytes
        );
    }
    Ok(())
}

/// The plan as JSON, every object naming its geometry (the plan's own
/// serialization leaves out `planes`, the default).
pub fn json(plan: &Plan) -> anyhow::Result<serde_json::Value> {
    let mut v = serde_json::to_value(plan)?;
    let objects = v
        .get_mut("objects")
        .and_then(serde_json::Value::as_array_mut)
        .context("a plan serializes with an objects list")?;
    for (j, o) in objects.iter_mut().zip(&plan.objects) {
        if let Some(map) = j.as_object_mut() {
            map.insert("geometry".into(), o.geometry.name().into());
        }
    }
    Ok(v)
}

/// The plan as a human-readable table.
pub fn table(plan: &Plan, budget: Budget) -> String {
    let mut s = String::new();
    let device = plan.device.as_deref().unwrap_or("-");
    let _ = writeln!(
        s,
        "{} plan on {}: budget {:.2} MB, planned in units of {} bytes ({} units)",
        plan.method,
        device,
        budget.total.as_mb(),
        budget.unit.0,
        budget.units()
    );
    let width = plan
        .objects
        .iter()
        .map(|o| o.name.chars().count())
        .max()
        .unwrap_or(0)
        .max("object".len());
    let _ = writeln!(
        s,
        "{:<width$}  {:>5}  {:>4}  {:<8}  {:>10}  {:>7}",
        "object", "g", "p", "geometry", "size MB", "SSIM"
    );
    for o in &plan.objects {
        let _ = writeln!(
            s,
            "{:<width$}  {:>5}  {:>4}  {:<8}  {:>10.2}  {:>7.4}",
            o.name,
            o.g,
            o.p,
            o.geometry.name(),
            Bytes(o.size_bytes).as_mb(),
            o.quality
        );
    }
    let _ = writeln!(
        s,
        "{:<width$}  {:>5}  {:>4}  {:<8}  {:>10.2}  {:>7.4}",
        "total",
        "",
        "",
        "",
        Bytes(plan.total_size_bytes).as_mb(),
        plan.total_quality
    );
    let used = if plan.budget_bytes == 0 {
        if plan.total_size_bytes == 0 {
            0.0
        } else {
            f64::INFINITY
        }
    } else {
        100.0 * plan.total_size_bytes as f64 / plan.budget_bytes as f64
    };
    let _ = writeln!(
        s,
        "budget used: {:.1} % ({:.2} of {:.2} MB){}",
        used,
        Bytes(plan.total_size_bytes).as_mb(),
        Bytes(plan.budget_bytes).as_mb(),
        if plan.feasible { "" } else { ": OVER BUDGET" }
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_size_margin_comes_off_the_budget() {
        assert_eq!(
            planning_budget(Bytes(240_000_000), 0.0).unwrap(),
            Bytes(240_000_000)
        );
        assert_eq!(
            planning_budget(Bytes(240_000_000), 10.0).unwrap(),
            Bytes(216_000_000)
        );
        // Rounded down: 1 byte less 50 % is 0, never 1.
        assert_eq!(planning_budget(Bytes(1), 50.0).unwrap(), Bytes(0));
        assert_eq!(planning_budget(Bytes(u64::MAX), 0.0).unwrap().0, u64::MAX);
        // A plan within the reduced budget measures within the whole one
        // when its sizes are under-predicted by at most the margin.
        let b = planning_budget(Bytes(150_000_000), 11.3).unwrap();
        let measured_at_worst = b.0 as f64 / (1.0 - 0.113);
        assert!(
            measured_at_worst <= 150_000_000.0 + 1.0,
            "{measured_at_worst}"
        );
    }

    #[test]
    fn a_bad_size_margin_names_the_flag() {
        for m in [-1.0, 100.0, 250.0, f64::NAN, f64::INFINITY] {
            let e = planning_budget(Bytes(100), m).unwrap_err().to_string();
            assert!(e.contains("--size-margin"), "{e}");
        }
    }
}

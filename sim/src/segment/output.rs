//! Building and writing the per-network training sets and
//! `segmentation.json`.

use super::analysis::{AlphaSource, Analysis, Decision, Decisions};
use super::enlarge::{enlarge_within, isolate, EnlargeOptions};
use super::frequency::FrequencyOptions;
use super::input::{SegCapture, SegFrame, SegmentError};
use crate::camera::Camera;
use crate::capture::{CaptureWriter, Split, OTHER_OBJECTS_MASK_VALUE};
use image::{imageops, GrayImage, RgbaImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Version of the `segmentation.json` layout written by this module.
pub const SEGMENTATION_VERSION: u32 = 1;
/// File name of the segmentation summary inside the output folder.
pub const SEGMENTATION_FILE: &str = "segmentation.json";

/// One network's training set: a dedicated object or the shared group.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// Dedicated (one object, enlarged views) or shared (original views).
    pub decision: Decision,
    /// Folder name under the output folder.
    pub folder: String,
    /// Object indices of the capture, in order; in the group's masks object
    /// `objects[i]` has label `i + 1`.
    pub objects: Vec<usize>,
}

/// The groups of a decision: one per dedicated object (in the capture's
/// order), then the shared group if any object is shared. Folder names are
/// the object names made file-safe, and `shared` (suffixed on collision).
pub fn plan_groups(cap: &SegCapture, decisions: &Decisions) -> Vec<Group> {
    let mut used: Vec<String> = Vec::new();
    let mut unique = |base: String| {
        let mut name = base.clone();
        let mut k = 2;
        while used.contains(&name) {
            name = format!("{base}-{k}");
            k += 1;
        }
        used.push(name.clone());
        name
    };
    let mut groups = Vec::new();
    for (o, d) in decisions.decisions.iter().enumerate() {
        if *d == Decision::Dedicated {
            groups.push(Group {
                decision: Decision::Dedicated,
                folder: unique(safe_name(&cap.objects[o])),
                objects: vec![o],
            });
        }
    }
    let shared: Vec<usize> = (0..decisions.decisions.len())
        .filter(|&o| decisions.decisions[o] == Decision::Shared)
        .collect();
    if !shared.is_empty() {
        groups.push(Group {
            decision: Decision::Shared,
            folder: unique("shared".into()),
            objects: shared,
        });
    }
    groups
}

fn safe_name(s: &str) -> String {
    let t: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if t.is_empty() || t.starts_with('.') {
        format!("object_{t}")
    } else {
        t
    }
}

/// One view of a group's training set.
#[derive(Debug, Clone)]
pub struct GroupView {
    /// `file_path` of the source frame (the written image keeps it).
    pub file_path: String,
    /// The image: enlarged (dedicated) or with other objects removed (shared).
    pub image: RgbaImage,
    /// The group's instance mask (label i + 1 = the group's i-th object,
    /// [`OTHER_OBJECTS_MASK_VALUE`] where an object outside the group
    /// covers the view, 0 elsewhere).
    pub mask: GrayImage,
    /// The camera that sees `image`.
    pub camera: Camera,
    /// Enlargement factors (x, y); (1, 1) for the shared group.
    pub zoom: (f64, f64),
}

/// The view of `group` made from `frame`; `None` when none of the group's
/// objects is visible in it (such frames are left out of the group's set).
/// Fails when the shared group mixes objects seen through different cameras
/// (only possible in 2-D composites of separate captures).
pub fn group_view(
    frame: &SegFrame,
    group: &Group,
    opts: &EnlargeOptions,
) -> Result<Option<GroupView>, SegmentError> {
    match group.decision {
        Decision::Dedicated => {
            let o = group.objects[0];
            Ok(enlarge_within(
                &frame.image,
                &frame.mask,
                (o + 1) as u8,
                &frame.camera_of(o),
                frame.region_of(o),
                opts,
            )
            .map(|e| GroupView {
                file_path: frame.file_path.clone(),
                image: e.image,
                mask: e.mask,
                camera: e.camera,
                zoom: e.zoom,
            }))
        }
        Decision::Shared => {
            let relabel = |l: u8| -> u8 {
                group
                    .objects
                    .iter()
                    .position(|&o| o + 1 == l as usize)
                    .map_or(0, |i| (i + 1) as u8)
            };
            let (camera, region) = (
                frame.camera_of(group.objects[0]),
                frame.region_of(group.objects[0]),
            );
            if group
                .objects
                .iter()
                .any(|&o| frame.camera_of(o) != camera || frame.region_of(o) != region)
            {
                return Err(SegmentError::Invalid(format!(
                    "{}: the shared group ({} objects) mixes objects seen through different cameras \
                     (a 2-D composite of separate captures); lower --alpha so each gets a dedicated network",
                    frame.file_path,
                    group.objects.len()
                )));
            }
            let (image, mask) = isolate(&frame.image, &frame.mask, relabel);
            if mask
                .as_raw()
                .iter()
                .all(|&v| v == 0 || v == OTHER_OBJECTS_MASK_VALUE)
            {
                return Ok(None);
            }
            // A composite's objects keep only their own part of the canvas.
            let (x0, y0, w, h) = (region.x0, region.y0, region.width(), region.height());
            let (image, mask) = if (w, h) == image.dimensions() {
                (image, mask)
            } else {
                (
                    imageops::crop_imm(&image, x0, y0, w, h).to_image(),
                    imageops::crop_imm(&mask, x0, y0, w, h).to_image(),
                )
            };
            let camera = Camera {
                intrinsics: camera
                    .intrinsics
                    .cropped(x0 as f32, y0 as f32, w as f32, h as f32, w, h),
                c2w: camera.c2w,
            };
            Ok(Some(GroupView {
                file_path: frame.file_path.clone(),
                image,
                mask,
                camera,
                zoom: (1.0, 1.0),
            }))
        }
    }
}

/// Builds the views of `group` from `frames` in parallel (rayon) and hands
/// each to `f`; returns how many were built (frames where none of the
/// group's objects is visible are skipped).
pub fn for_each_view<F>(
    frames: &[SegFrame],
    group: &Group,
    opts: &EnlargeOptions,
    f: F,
) -> Result<usize, SegmentError>
where
    F: Fn(GroupView) -> Result<(), SegmentError> + Sync,
{
    frames
        .par_iter()
        .map(|frame| match group_view(frame, group, opts)? {
            Some(v) => f(v).map(|()| 1),
            None => Ok(0),
        })
        .try_reduce(|| 0, |a, b| Ok(a + b))
}

/// Settings of a whole segmentation run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SegmentOptions {
    /// Threshold α (cycles per object diameter); `None` = the lowest maximum.
    pub alpha: Option<f64>,
    /// The frequency measure.
    pub frequency: FrequencyOptions,
    /// The enlargement.
    pub enlarge: EnlargeOptions,
}

/// `segmentation.json`: what the later stages read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Segmentation {
    /// Layout version ([`SEGMENTATION_VERSION`]).
    pub version: u32,
    /// The capture it was computed from.
    pub capture: String,
    /// Image width of the capture (and of every written view), pixels.
    pub image_width: u32,
    /// Image height, pixels.
    pub image_height: u32,
    /// How frequencies were measured.
    pub measure: MeasureInfo,
    /// Threshold α, in the measure's unit.
    pub alpha: f64,
    /// Where α came from.
    pub alpha_source: AlphaSource,
    /// The decision rule, in words.
    pub rule: String,
    /// Per object, in the capture's order.
    pub objects: Vec<ObjectRecord>,
    /// One per network to train: its folder and objects.
    pub groups: Vec<GroupRecord>,
    /// Wall-clock seconds of the stages.
    pub timings: Timings,
}

/// The frequency measure's definition, for readers of the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeasureInfo {
    /// Short name of the measure.
    pub name: String,
    /// Unit of every frequency in the file (except `cycles_per_pixel`).
    pub unit: String,
    /// Share of spectral energy below the frequency.
    pub energy_share: f64,
    /// Band counted, cycles per object diameter (null: up to the pixels).
    pub band: Option<f64>,
    /// Views with fewer object pixels give no value.
    pub min_pixels: u32,
}

/// One object's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectRecord {
    /// Object name.
    pub name: String,
    /// Its label in the capture's instance masks.
    pub label: u8,
    /// Maximum detail frequency over the training views.
    pub max_frequency: f64,
    /// `file_path` of the view where the maximum is reached.
    pub peak_image: String,
    /// Dedicated or shared.
    pub decision: Decision,
    /// Training folder of its network, relative to `segmentation.json`.
    pub folder: String,
    /// Index into `groups`.
    pub group: usize,
    /// Per training view.
    pub per_image: Vec<ImageRecord>,
}

/// One object in one training view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageRecord {
    /// The view's `file_path`.
    pub image: String,
    /// Detail frequency (cycles per object diameter); null if too small.
    pub frequency: Option<f64>,
    /// The same in cycles per pixel.
    pub cycles_per_pixel: Option<f64>,
    /// Object diameter in pixels (2·√2·radius of gyration).
    pub diameter_px: Option<f64>,
    /// Whether the view resolves the whole band (diameter ≥ 2·band pixels).
    pub band_resolved: Option<bool>,
}

/// One network's training set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupRecord {
    /// Dedicated or shared.
    pub decision: Decision,
    /// Folder relative to `segmentation.json`: a NeRF-synthetic capture.
    pub folder: String,
    /// Its objects; in its masks object i has label i + 1.
    pub objects: Vec<String>,
    /// Training views written.
    pub train_frames: usize,
    /// Held-out views written.
    pub test_frames: usize,
    /// Mean enlargement factor over the training views (1 for shared).
    pub mean_zoom: f64,
    /// Width of its views, pixels.
    pub image_width: u32,
    /// Height of its views, pixels.
    pub image_height: u32,
}

/// Wall-clock seconds of each stage.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Timings {
    /// Frequency analysis of every object in every training view.
    pub analyse_s: f64,
    /// Building (enlarging / masking), encoding and writing the views.
    pub views_s: f64,
    /// Everything.
    pub total_s: f64,
}

impl Segmentation {
    /// Reads and checks a `segmentation.json`.
    pub fn read(path: &Path) -> Result<Self, SegmentError> {
        let text = crate::validate::read_to_string(path).map_err(|source| SegmentError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let s: Segmentation = serde_json::from_str(&text).map_err(|e| {
            SegmentError::Invalid(format!(
                "{}: invalid segmentation JSON: {e}",
                path.display()
            ))
        })?;
        if s.version != SEGMENTATION_VERSION {
            return Err(SegmentError::Invalid(format!(
                "{}: version {} (this build reads version {SEGMENTATION_VERSION})",
                path.display(),
                s.version
            )));
        }
        for o in &s.objects {
            if s.groups
                .get(o.group)
                .is_none_or(|g| !g.objects.contains(&o.name))
            {
                return Err(SegmentError::Invalid(format!(
                    "{}: object {:?}: group {} does not list it",
                    path.display(),
                    o.name,
                    o.group
                )));
            }
        }
        Ok(s)
    }

    /// The object record named `name`.
    pub fn object(&self, name: &str) -> Option<&ObjectRecord> {
        self.objects.iter().find(|o| o.name == name)
    }
}

/// The whole stage: analyse, decide, write one NeRF-synthetic folder per
/// network under `out` and `out/segmentation.json`. Each folder is written
/// beside its final place and renamed into it when complete, and the JSON
/// last, so an interrupted run never leaves a half-written set under a
/// final name.
pub fn segment(
    cap: &SegCapture,
    opts: &SegmentOptions,
    out: &Path,
) -> Result<Segmentation, SegmentError> {
    let t0 = std::time::Instant::now();
    let analysis = super::analysis::analyse(cap, &opts.frequency)?;
    let analyse_s = t0.elapsed().as_secs_f64();
    let decisions = super::analysis::decide(&analysis, opts.alpha)?;
    let groups = plan_groups(cap, &decisions);
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SegmentError::Io { path, source }
    };
    // Refuse an impossible shared group before writing anything.
    for g in groups.iter().filter(|g| g.objects.len() > 1) {
        for f in cap.train.iter().chain(&cap.test) {
            let first = (f.camera_of(g.objects[0]), f.region_of(g.objects[0]));
            if g.objects
                .iter()
                .any(|&o| (f.camera_of(o), f.region_of(o)) != first)
            {
                return Err(SegmentError::Invalid(format!(
                    "{}: the shared group ({}) mixes objects seen through different cameras \
                     (a 2-D composite of separate captures); lower --alpha so each gets a dedicated network",
                    f.file_path,
                    g.objects.iter().map(|&o| cap.objects[o].as_str()).collect::<Vec<_>>().join(", ")
                )));
            }
        }
    }
    // The output folder is replaced whole: built beside `out`, swapped in
    // only when every group and segmentation.json are written, so a failure
    // leaves the old segmentation as it was and a success leaves no stale
    // group folders. Anything in `out` we did not write is refused first.
    let ours = owned_entries(out);
    let ours = |name: &str| ours.iter().any(|n| n == name);
    crate::output::check_replaceable(out, &ours, SEGMENT_DIR_HINT)?;
    let stage = crate::output::StagedDir::new(out)?;
    let t1 = std::time::Instant::now();
    let mut records = Vec::new();
    for g in &groups {
        records.push(write_group(cap, g, &opts.enlarge, stage.path())?);
    }
    let views_s = t1.elapsed().as_secs_f64();
    let seg = summary(cap, &analysis, &decisions, &groups, records, opts, {
        Timings {
            analyse_s,
            views_s,
            total_s: t0.elapsed().as_secs_f64(),
        }
    });
    let text = serde_json::to_string_pretty(&seg)
        .map_err(|e| SegmentError::Invalid(format!("cannot encode segmentation.json: {e}")))?;
    let path = stage.path().join(SEGMENTATION_FILE);
    std::fs::write(&path, text).map_err(io(&path))?;
    stage.commit(&ours, SEGMENT_DIR_HINT)?;
    Ok(seg)
}

const SEGMENT_DIR_HINT: &str =
    "a segmentation folder is replaced whole; move that away or choose another --out";

/// What a segmentation folder holds that we wrote: segmentation.json and
/// the group folders it lists.
fn owned_entries(out: &Path) -> Vec<String> {
    let mut names = vec![SEGMENTATION_FILE.to_string()];
    if let Ok(old) = Segmentation::read(&out.join(SEGMENTATION_FILE)) {
        names.extend(old.groups.into_iter().map(|g| g.folder));
    }
    names
}

impl From<crate::output::OutputError> for SegmentError {
    fn from(e: crate::output::OutputError) -> Self {
        SegmentError::Invalid(e.to_string())
    }
}

fn summary(
    cap: &SegCapture,
    analysis: &Analysis,
    decisions: &Decisions,
    groups: &[Group],
    records: Vec<GroupRecord>,
    opts: &SegmentOptions,
    timings: Timings,
) -> Segmentation {
    let (w, h) = cap.image_size();
    let objects = analysis
        .objects
        .iter()
        .enumerate()
        .map(|(o, a)| {
            let group = groups
                .iter()
                .position(|g| g.objects.contains(&o))
                .unwrap_or(0);
            ObjectRecord {
                name: a.name.clone(),
                label: a.label,
                max_frequency: a.max_frequency,
                peak_image: a.peak_image.clone(),
                decision: decisions.decisions[o],
                folder: groups
                    .get(group)
                    .map_or_else(String::new, |g| g.folder.clone()),
                group,
                per_image: a
                    .per_image
                    .iter()
                    .map(|(image, d)| ImageRecord {
                        image: image.clone(),
                        frequency: d.map(|d| d.cycles_per_diameter),
                        cycles_per_pixel: d.map(|d| d.cycles_per_pixel),
                        diameter_px: d.map(|d| d.diameter_px),
                        band_resolved: d.map(|d| d.band_resolved),
                    })
                    .collect(),
            }
        })
        .collect();
    Segmentation {
        version: SEGMENTATION_VERSION,
        capture: cap.source.clone(),
        image_width: w,
        image_height: h,
        measure: MeasureInfo {
            name: "spectral energy radius of the mean-removed, windowed masked luminance, within a band"
                .into(),
            unit: "cycles per object diameter (2·√2·radius of gyration of its mask)".into(),
            energy_share: opts.frequency.energy_share,
            band: opts.frequency.band,
            min_pixels: opts.frequency.min_pixels,
        },
        alpha: decisions.alpha,
        alpha_source: decisions.alpha_source,
        rule: "dedicated network iff max_frequency > alpha; the others share one network".into(),
        objects,
        groups: records,
        timings,
    }
}

/// Writes one group's folder (through [`CaptureWriter`], so it is a
/// capture like any other); returns its record.
fn write_group(
    cap: &SegCapture,
    group: &Group,
    opts: &EnlargeOptions,
    out: &Path,
) -> Result<GroupRecord, SegmentError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SegmentError::Io { path, source }
    };
    let final_dir = out.join(&group.folder);
    let tmp_dir = out.join(format!(".{}.partial", group.folder));
    if tmp_dir.exists() {
        std::fs::remove_dir_all(&tmp_dir).map_err(io(&tmp_dir))?;
    }
    match write_group_into(cap, group, opts, &tmp_dir) {
        Ok(record) => {
            replace_dir(&tmp_dir, &final_dir)?;
            Ok(record)
        }
        Err(e) => {
            // Best effort: the error matters more than the leftover.
            let _ = std::fs::remove_dir_all(&tmp_dir);
            Err(e)
        }
    }
}

fn write_group_into(
    cap: &SegCapture,
    group: &Group,
    opts: &EnlargeOptions,
    tmp_dir: &Path,
) -> Result<GroupRecord, SegmentError> {
    let writer = CaptureWriter::create(tmp_dir, cap.camera_angle_x)?;
    // Where objects outside the group hid it is recorded only when the
    // folder gets a scene.json declaring the value (without one, a mask
    // value names an object), and only if there are such objects: some
    // outside the group, or outside the source folder itself (a group
    // folder segmented again).
    let mark_others = cap.scene.as_ref().is_some_and(|s| {
        group.objects.len() < s.objects.len() || s.other_objects_mask_value.is_some()
    });
    let size: Mutex<Option<(u32, u32, String)>> = Mutex::new(None);
    let mut counts = [0usize; 2];
    let mut zoom_sum = 0.0;
    for (split, frames) in [(Split::Train, &cap.train), (Split::Test, &cap.test)] {
        // Each written view's zoom, in view order: summed in that order so
        // `mean_zoom` is the same to the last bit on every run (a shared
        // accumulator added them in the threads' order).
        let zooms = frames
            .par_iter()
            .enumerate()
            .map(|(index, f)| -> Result<Option<f64>, SegmentError> {
                let Some(mut v) = group_view(f, group, opts)? else {
                    return Ok(None);
                };
                if !mark_others {
                    for m in v.mask.iter_mut() {
                        if *m == OTHER_OBJECTS_MASK_VALUE {
                            *m = 0;
                        }
                    }
                }
                {
                    let mut s = size.lock().unwrap_or_else(|e| e.into_inner());
                    let (w, h) = v.image.dimensions();
                    match &*s {
                        Some((sw, sh, first)) if (*sw, *sh) != (w, h) => {
                            return Err(SegmentError::Invalid(format!(
                                "{}: group {:?}: view {} is {w}×{h}, view {first} is {sw}×{sh}",
                                cap.source, group.folder, v.file_path
                            )));
                        }
                        Some(_) => {}
                        None => *s = Some((w, h, v.file_path.clone())),
                    }
                }
                let stem = v.file_path.rsplit('/').next().unwrap_or(&v.file_path);
                writer.write_frame(split, index, stem, &v.camera, &v.image, Some(&v.mask))?;
                Ok(Some(0.5 * (v.zoom.0 + v.zoom.1)))
            })
            .collect::<Result<Vec<_>, SegmentError>>()?;
        let n = zooms.iter().flatten().count();
        if n == 0 && split == Split::Train {
            return Err(SegmentError::Invalid(format!(
                "{}: group {:?} is visible in no training view",
                cap.source, group.folder
            )));
        }
        counts[usize::from(split == Split::Test)] = n;
        if split == Split::Train {
            zoom_sum = zooms.iter().flatten().sum();
        }
    }
    // The group's own scene.json: its objects' entries, renumbered 1..n.
    let scene = cap.scene.as_ref().map(|s| {
        let mut g = s.clone();
        g.objects = group
            .objects
            .iter()
            .enumerate()
            .filter_map(|(i, &o)| {
                s.objects.get(o).cloned().map(|mut info| {
                    info.mask_value = (i + 1) as u8;
                    info
                })
            })
            .collect();
        g.other_objects_mask_value = mark_others.then_some(OTHER_OBJECTS_MASK_VALUE);
        g
    });
    writer.finish(scene.as_ref())?;
    let (image_width, image_height, _) = size
        .into_inner()
        .unwrap_or_else(|e| e.into_inner())
        .unwrap_or_default();
    Ok(GroupRecord {
        image_width,
        image_height,
        decision: group.decision,
        folder: group.folder.clone(),
        objects: group
            .objects
            .iter()
            .map(|&o| cap.objects[o].clone())
            .collect(),
        train_frames: counts[0],
        test_frames: counts[1],
        mean_zoom: zoom_sum / counts[0].max(1) as f64,
    })
}

/// Moves a finished folder into place, replacing an older one only once the
/// new one is complete.
fn replace_dir(tmp: &Path, target: &Path) -> Result<(), SegmentError> {
    let io = |path: PathBuf| move |source| SegmentError::Io { path, source };
    if target.exists() {
        let old = target.with_file_name(format!(
            ".{}.old",
            target
                .file_name()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
        ));
        if old.exists() {
            std::fs::remove_dir_all(&old).map_err(io(old.clone()))?;
        }
        std::fs::rename(target, &old).map_err(io(target.to_path_buf()))?;
        std::fs::rename(tmp, target).map_err(io(target.to_path_buf()))?;
        std::fs::remove_dir_all(&old).map_err(io(old))?;
    } else {
        std::fs::rename(tmp, target).map_err(io(target.to_path_buf()))?;
    }
    Ok(())
}

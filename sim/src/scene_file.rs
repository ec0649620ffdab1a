//! The scene file (JSON): the objects to plan and, per object, its
//! configurations — either a measured table or fitted profile parameters.
//!
//! Table form (exactly as issue 2 specifies; extra fields are allowed and
//! ignored; `quality` is SSIM in `[0, 1]`; `size_bytes` a non-negative
//! number of bytes, rounded up to a whole byte):
//!
//! ```json
//! {"objects": [{"name": "lego", "configs": [
//!     {"g": 128, "p": 17, "size_bytes": 104857600, "quality": 0.951}, …]}, …]}
//! ```
//!
//! Profile form (an object has `profile` instead of `configs`): the white-box
//! profiler's fitted parameters and the (g, p) values to evaluate, as
//! `nerflex profile fit` writes them:
//!
//! ```json
//! {"name": "lego", "profile": {
//!     "size":    {"k": 0.17, "a": 0.0, "b": 0.0, "m": 2.0e6, "g_power": 3},
//!     "quality": {"k": 3.2e6, "a": 32.0, "b": 4.0, "m": 0.953},
//!     "g": [32, 64, 128], "p": [5, 9, 17]}}
//! ```
//!
//! with size `S(g,p) = k·(g+a)^e·(p+b)² + c·(g+a)² + m` in bytes (grows with
//! g and p) and quality `Q(g,p) = m − k/((g+a)^e·(p+b)²)` (saturates), where
//! `e` is the optional `g_power`: 3 (the NeRFlex paper's voxel count, the
//! default), 2 (surface-like growth) or 1.5 (the quads family's texel term),
//! and `c` the size's optional per-quad term (bytes per unit of `(g+a)²`,
//! 0 when absent; the quality has none). Every (g, p) pair of the two lists becomes one
//! configuration, evaluated by the fixed-point `nerflex_core::profiler`
//! exactly as on the device: sizes rounded up to whole bytes, qualities to
//! Q1.31 and clamped to `[0, 1]` (a fitted curve may overshoot). Parameters
//! and (g, p) must lie in that module's documented range (e.g. `k ≥ 0`,
//! `g + a ≥ 0.5`); anything else is an error naming the field. Extra fields
//! (such as the fit's `"fit"` diagnostics) are ignored.
//!
//! **Geometry.** A configuration is baked as `planes` (quads per shell
//! voxel, the default) or `mesh` (one connected mesh; `nerflex bake
//! --surface mesh`), see [`crate::geometry`]. A table row may say which
//! with `"geometry": "planes" | "mesh"`; absent means `planes`, so every
//! older file reads as before. A row is identified by (g, p, geometry). An
//! object may carry one profile per geometry:
//!
//! ```json
//! {"name": "lego", "profiles": {"planes": {…}, "mesh": {…}}}
//! ```
//!
//! each in the profile form above; the old single `"profile"` is the
//! planes profile (`"profile"` and `"profiles"` together are an error).
//! The object's configurations are the union: each profile evaluated on
//! its own (g, p) lists, planes first (at most 256 in all). The planner
//! then picks one (g, p, geometry) per object ([`crate::baselines`]).
//!
//! An optional top-level `"single"` entry (same shape as an object; `name`
//! optional, default `"single"`) gives the configurations of one network for
//! the whole scene, used by the Single-NeRF baseline.
//!
//! Errors name the file and the field, e.g.
//! `scene.json: objects[2].configs[5].size_bytes: negative value -3`.

use crate::geometry::Geometry;
use nerflex_core::profiler::{Family, ProfileError};
use nerflex_core::units::{Bytes, UnitError};
use serde_json::{Map, Number, Value};
use std::collections::HashMap;
use std::fmt;
use std::path::Path;

/// Most configurations an object may have (the solver stores `u8` indices).
pub const MAX_CONFIGS: usize = nerflex_core::mck::MAX_CONFIGS;

/// A scene: the objects to plan.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The objects, in file order (names are unique).
    pub objects: Vec<SceneObject>,
    /// Optional measured configurations of one network for the whole scene.
    pub single: Option<SceneObject>,
}

/// One object and its configurations.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    /// Unique name.
    pub name: String,
    /// Configurations: the table, or the profile evaluated on its (g, p) grid.
    pub configs: Vec<ConfigEntry>,
    /// The planes profile the configurations were evaluated from, if any
    /// (JSON `"profile"` or `"profiles"."planes"`).
    pub profile: Option<Profile>,
    /// The mesh profile, if any (JSON `"profiles"."mesh"`); its
    /// configurations follow the planes profile's in `configs`.
    pub mesh_profile: Option<Profile>,
}

impl SceneObject {
    /// The object's profile of `geometry`, if it has one.
    pub fn profile_of(&self, geometry: Geometry) -> Option<&Profile> {
        match geometry {
            Geometry::Planes => self.profile.as_ref(),
            Geometry::Mesh => self.mesh_profile.as_ref(),
        }
    }

    /// The geometries its configurations use, in [`Geometry::ALL`] order.
    pub fn geometries(&self) -> Vec<Geometry> {
        Geometry::ALL
            .into_iter()
            .filter(|&g| self.configs.iter().any(|c| c.geometry == g))
            .collect()
    }
}

/// One configuration (g, p, geometry) of an object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConfigEntry {
    /// Voxel grid resolution per axis.
    pub g: u32,
    /// Texel patch size per quad (p × p).
    pub p: u32,
    /// Size of the baked data.
    pub size: Bytes,
    /// Predicted or measured SSIM in `[0, 1]`.
    pub quality: f64,
    /// The geometry it is baked with.
    pub geometry: Geometry,
}

impl ConfigEntry {
    /// A planes configuration.
    pub fn planes(g: u32, p: u32, size: Bytes, quality: f64) -> ConfigEntry {
        ConfigEntry {
            g,
            p,
            size,
            quality,
            geometry: Geometry::Planes,
        }
    }
}

/// Fitted profile of one object (see the module docs for the formulas).
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// Size model `S(g,p) = k·(g+a)³·(p+b)² + m` (bytes).
    pub size: ModelParams,
    /// Quality model `Q(g,p) = m − k/((g+a)³·(p+b)²)` (SSIM).
    pub quality: ModelParams,
    /// Grid resolutions to evaluate.
    pub g: Vec<u32>,
    /// Patch sizes to evaluate.
    pub p: Vec<u32>,
}

/// The parameters of one profile curve: `k`, `a`, `b`, `m` and the family
/// (the power of `g + a`), shared with `nerflex_core::profiler`.
pub type ModelParams = nerflex_core::profiler::Params;

/// One model's parameters in the profile form: `k, a, b, m, g_power`, plus
/// `c` when it is not 0 (so profiles without the per-quad term are written
/// exactly as before it existed). `g_power` is an integer for the volume
/// and surface families and 1.5 for the quads family.
pub fn params_json(m: &ModelParams) -> Value {
    let g_power = match m.family.g_power_halves() {
        h if h % 2 == 0 => Value::from(h / 2),
        _ => Value::from(m.family.g_power()),
    };
    let mut v = serde_json::json!({"k": m.k, "a": m.a, "b": m.b, "m": m.m, "g_power": g_power});
    if m.c != 0.0 {
        v["c"] = Value::from(m.c);
    }
    v
}

impl Profile {
    /// Predicted size in bytes, `f64` (not rounded): `k·(g+a)^e·(p+b)² + m`.
    pub fn size_at(&self, g: f64, p: f64) -> f64 {
        self.size.size_f64(g, p)
    }

    /// Predicted SSIM, `f64` (not clamped): `m − k/((g+a)^e·(p+b)²)`.
    pub fn quality_at(&self, g: f64, p: f64) -> f64 {
        self.quality.quality_f64(g, p)
    }

    /// Partial derivatives (dS/dg, dS/dp) at (g, p).
    pub fn size_gradient(&self, g: f64, p: f64) -> (f64, f64) {
        let s = &self.size;
        let (gg, pp) = (g + s.a, p + s.b);
        let x = s.volume_f64(g, p);
        let e = s.family.g_power();
        (e * s.k * x / gg + 2.0 * s.c * gg, 2.0 * s.k * x / pp)
    }

    /// Partial derivatives (dQ/dg, dQ/dp) at (g, p).
    pub fn quality_gradient(&self, g: f64, p: f64) -> (f64, f64) {
        let q = &self.quality;
        let (gg, pp) = (g + q.a, p + q.b);
        let x = q.volume_f64(g, p);
        let e = q.family.g_power();
        (e * q.k / (x * gg), 2.0 * q.k / (x * pp))
    }

    /// The profile in the scene file's profile form.
    pub fn to_json(&self) -> Value {
        serde_json::json!({
            "size": params_json(&self.size),
            "quality": params_json(&self.quality),
            "g": self.g,
            "p": self.p,
        })
    }

    /// The profile in fixed point (`nerflex_core::profiler`).
    pub fn fixed(&self) -> Result<nerflex_core::profiler::Profile, ProfileError> {
        nerflex_core::profiler::Profile::from_params(&self.size, &self.quality)
    }
}

/// A scene file problem: which file, which field, what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    /// The file (as given) or another origin label.
    pub origin: String,
    /// JSON path of the field, e.g. `objects[2].configs[5].size_bytes`
    /// (empty for whole-file problems).
    pub field: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.field.is_empty() {
            write!(f, "{}: {}", self.origin, self.message)
        } else {
            write!(f, "{}: {}: {}", self.origin, self.field, self.message)
        }
    }
}

impl std::error::Error for SceneError {}

/// Reads and validates a scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let origin = path.display().to_string();
    let text = crate::validate::read_to_string(path).map_err(|e| SceneError {
        origin: origin.clone(),
        field: String::new(),
        message: format!("cannot read: {e}"),
    })?;
    parse(&text, &origin)
}

/// Parses and validates scene JSON; `origin` names it in errors.
pub fn parse(text: &str, origin: &str) -> Result<Scene, SceneError> {
    let value: Value = serde_json::from_str(text).map_err(|e| SceneError {
        origin: origin.to_string(),
        field: String::new(),
        message: format!("invalid JSON: {e}"),
    })?;
    Parser { origin }.scene(&value)
}

impl Scene {
    /// The scene as JSON in the file format (profile objects are written in
    /// profile form, the others as tables).
    pub fn to_json(&self) -> Value {
        let mut root = Map::new();
        root.insert(
            "objects".into(),
            Value::Array(self.objects.iter().map(SceneObject::to_json).collect()),
        );
        if let Some(single) = &self.single {
            root.insert("single".into(), single.to_json());
        }
        Value::Object(root)
    }
}

impl SceneObject {
    fn to_json(&self) -> Value {
        let mut obj = Map::new();
        obj.insert("name".into(), Value::String(self.name.clone()));
        match (&self.profile, &self.mesh_profile) {
            // Planes only: the older single-profile form, unchanged.
            (Some(p), None) => {
                obj.insert("profile".into(), p.to_json());
            }
            (None, None) => {
                let configs = self
                    .configs
                    .iter()
                    .map(|c| {
                        let mut row = serde_json::json!({"g": c.g, "p": c.p, "size_bytes": c.size.0, "quality": c.quality});
                        if !c.geometry.is_planes() {
                            row["geometry"] = Value::String(c.geometry.name().into());
                        }
                        row
                    })
                    .collect();
                obj.insert("configs".into(), Value::Array(configs));
            }
            (planes, mesh) => {
                let mut profiles = Map::new();
                for (g, p) in [(Geometry::Planes, planes), (Geometry::Mesh, mesh)] {
                    if let Some(p) = p {
                        profiles.insert(g.name().into(), p.to_json());
                    }
                }
                obj.insert("profiles".into(), Value::Object(profiles));
            }
        }
        Value::Object(obj)
    }
}

struct Parser<'o> {
    origin: &'o str,
}

impl Parser<'_> {
    fn err(&self, field: &str, message: impl Into<String>) -> SceneError {
        SceneError {
            origin: self.origin.to_string(),
            field: field.to_string(),
            message: message.into(),
        }
    }

    fn scene(&self, v: &Value) -> Result<Scene, SceneError> {
        let root = v
            .as_object()
            .ok_or_else(|| self.err("", "expected a JSON object with an \"objects\" list"))?;
        let list = root
            .get("objects")
            .ok_or_else(|| self.err("objects", "missing"))?
            .as_array()
            .ok_or_else(|| self.err("objects", "expected a list of objects"))?;
        if list.is_empty() {
            return Err(self.err("objects", "empty list: a scene needs at least one object"));
        }
        let mut objects = Vec::with_capacity(list.len());
        let mut seen: HashMap<String, usize> = HashMap::new();
        for (i, item) in list.iter().enumerate() {
            let path = format!("objects[{i}]");
            let object = self.object(item, &path, None)?;
            if let Some(first) = seen.insert(object.name.clone(), i) {
                return Err(self.err(
                    &format!("{path}.name"),
                    format!("duplicate name {:?} (also objects[{first}])", object.name),
                ));
            }
            objects.push(object);
        }
        let single = match root.get("single") {
            None | Some(Value::Null) => None,
            Some(s) => Some(self.object(s, "single", Some("single"))?),
        };
        Ok(Scene { objects, single })
    }

    fn object(
        &self,
        v: &Value,
        path: &str,
        default_name: Option<&str>,
    ) -> Result<SceneObject, SceneError> {
        let obj = v.as_object().ok_or_else(|| {
            self.err(
                path,
                "expected an object with \"name\" and \"configs\" or \"profile\"",
            )
        })?;
        let name = match (obj.get("name"), default_name) {
            (None, Some(d)) => d.to_string(),
            (None, None) => return Err(self.err(&format!("{path}.name"), "missing")),
            (Some(Value::String(s)), _) if !s.trim().is_empty() => s.clone(),
            (Some(Value::String(_)), _) => {
                return Err(self.err(&format!("{path}.name"), "empty name"))
            }
            (Some(other), _) => {
                return Err(self.err(
                    &format!("{path}.name"),
                    format!("expected a string, got {other}"),
                ))
            }
        };
        let given: Vec<&str> = ["configs", "profile", "profiles"]
            .into_iter()
            .filter(|k| obj.contains_key(*k))
            .collect();
        if given.len() > 1 {
            return Err(self.err(
                path,
                format!(
                    "has both {}; give one of \"configs\", \"profile\" or \"profiles\"",
                    given
                        .iter()
                        .map(|k| format!("\"{k}\""))
                        .collect::<Vec<_>>()
                        .join(" and ")
                ),
            ));
        }
        match (obj.get("configs"), obj.get("profile"), obj.get("profiles")) {
            (Some(c), _, _) => Ok(SceneObject {
                configs: self.table(c, &format!("{path}.configs"), &name)?,
                name,
                profile: None,
                mesh_profile: None,
            }),
            (_, Some(p), _) => {
                let ppath = format!("{path}.profile");
                let profile = self.profile(p, &ppath)?;
                let configs = self.evaluate(&profile, &ppath, Geometry::Planes)?;
                Ok(SceneObject {
                    name,
                    configs,
                    profile: Some(profile),
                    mesh_profile: None,
                })
            }
            (_, _, Some(ps)) => self.profiles(ps, &format!("{path}.profiles"), name),
            _ => Err(self.err(path, "needs \"configs\", \"profile\" or \"profiles\"")),
        }
    }

    /// `"profiles": {"planes": …, "mesh": …}`: one profile per geometry.
    fn profiles(&self, v: &Value, path: &str, name: String) -> Result<SceneObject, SceneError> {
        let map = v.as_object().ok_or_else(|| {
            self.err(
                path,
                format!(
                    "object {name:?}: expected an object of profiles by geometry (planes, mesh)"
                ),
            )
        })?;
        if map.is_empty() {
            return Err(self.err(path, format!("object {name:?}: no profiles")));
        }
        if let Some(bad) = map.keys().find(|k| Geometry::parse(k).is_none()) {
            return Err(self.err(
                &format!("{path}.{bad}"),
                format!("object {name:?}: unknown geometry {bad:?}; expected planes or mesh"),
            ));
        }
        let mut object = SceneObject {
            name,
            configs: Vec::new(),
            profile: None,
            mesh_profile: None,
        };
        for geometry in Geometry::ALL {
            let Some(p) = map.get(geometry.name()) else {
                continue;
            };
            let ppath = format!("{path}.{geometry}");
            let profile = self.profile(p, &ppath)?;
            object
                .configs
                .extend(self.evaluate(&profile, &ppath, geometry)?);
            match geometry {
                Geometry::Planes => object.profile = Some(profile),
                Geometry::Mesh => object.mesh_profile = Some(profile),
            }
        }
        if object.configs.len() > MAX_CONFIGS {
            return Err(self.err(
                path,
                format!(
                    "object {:?}: {} configurations over all geometries; at most {MAX_CONFIGS} are supported",
                    object.name,
                    object.configs.len()
                ),
            ));
        }
        Ok(object)
    }

    fn table(&self, v: &Value, path: &str, name: &str) -> Result<Vec<ConfigEntry>, SceneError> {
        let list = v
            .as_array()
            .ok_or_else(|| self.err(path, "expected a list of configurations"))?;
        if list.is_empty() {
            return Err(self.err(
                path,
                "empty list: an object needs at least one configuration",
            ));
        }
        if list.len() > MAX_CONFIGS {
            return Err(self.err(
                path,
                format!(
                    "{} configurations; at most {MAX_CONFIGS} are supported",
                    list.len()
                ),
            ));
        }
        let mut seen: HashMap<(u32, u32, Geometry), usize> = HashMap::new();
        let mut out = Vec::with_capacity(list.len());
        for (j, item) in list.iter().enumerate() {
            let cpath = format!("{path}[{j}]");
            let c = item.as_object().ok_or_else(|| {
                self.err(&cpath, "expected an object with g, p, size_bytes, quality")
            })?;
            let g = self.positive_int(c, &cpath, "g")?;
            let p = self.positive_int(c, &cpath, "p")?;
            let size = self.size_bytes(c, &cpath)?;
            let quality = self.quality(c, &cpath)?;
            let geometry = self.geometry(c, &cpath, name)?;
            if let Some(first) = seen.insert((g, p, geometry), j) {
                let what = if geometry.is_planes() {
                    String::new()
                } else {
                    format!(", {geometry}")
                };
                return Err(self.err(
                    &cpath,
                    format!("duplicate configuration (g {g}, p {p}{what}) (also {path}[{first}])"),
                ));
            }
            out.push(ConfigEntry {
                g,
                p,
                size,
                quality,
                geometry,
            });
        }
        Ok(out)
    }

    /// A row's optional `"geometry"` (absent: planes).
    fn geometry(
        &self,
        obj: &Map<String, Value>,
        path: &str,
        name: &str,
    ) -> Result<Geometry, SceneError> {
        match obj.get("geometry") {
            None => Ok(Geometry::Planes),
            Some(Value::String(s)) => Geometry::parse(s).ok_or_else(|| {
                self.err(
                    &format!("{path}.geometry"),
                    format!("object {name:?}: unknown geometry {s:?}; expected planes or mesh"),
                )
            }),
            Some(other) => Err(self.err(
                &format!("{path}.geometry"),
                format!("object {name:?}: expected \"planes\" or \"mesh\", got {other}"),
            )),
        }
    }

    fn field<'v>(
        &self,
        obj: &'v Map<String, Value>,
        path: &str,
        key: &str,
    ) -> Result<&'v Value, SceneError> {
        obj.get(key)
            .ok_or_else(|| self.err(&format!("{path}.{key}"), "missing"))
    }

    fn number(
        &self,
        obj: &Map<String, Value>,
        path: &str,
        key: &str,
    ) -> Result<(f64, Number), SceneError> {
        match self.field(obj, path, key)? {
            Value::Number(n) => {
                let x = n.as_f64().ok_or_else(|| {
                    self.err(
                        &format!("{path}.{key}"),
                        format!("not a finite number ({n})"),
                    )
                })?;
                if !x.is_finite() {
                    return Err(self.err(
                        &format!("{path}.{key}"),
                        format!("not a finite number ({n})"),
                    ));
                }
                Ok((x, n.clone()))
            }
            other => Err(self.err(
                &format!("{path}.{key}"),
                format!("expected a number, got {other}"),
            )),
        }
    }

    fn positive_int(
        &self,
        obj: &Map<String, Value>,
        path: &str,
        key: &str,
    ) -> Result<u32, SceneError> {
        let (x, n) = self.number(obj, path, key)?;
        let fpath = format!("{path}.{key}");
        if x < 0.0 {
            return Err(self.err(&fpath, format!("negative value {n}")));
        }
        match n.as_u64().and_then(|v| u32::try_from(v).ok()) {
            Some(v) if v > 0 => Ok(v),
            _ => Err(self.err(&fpath, format!("must be a positive integer, got {n}"))),
        }
    }

    fn size_bytes(&self, obj: &Map<String, Value>, path: &str) -> Result<Bytes, SceneError> {
        let (x, n) = self.number(obj, path, "size_bytes")?;
        let fpath = format!("{path}.size_bytes");
        if let Some(v) = n.as_u64() {
            return Ok(Bytes(v));
        }
        Bytes::from_f64_ceil(x).map_err(|e| match e {
            UnitError::Negative(_) => self.err(&fpath, format!("negative value {n}")),
            other => self.err(&fpath, other.to_string()),
        })
    }

    fn quality(&self, obj: &Map<String, Value>, path: &str) -> Result<f64, SceneError> {
        let (x, n) = self.number(obj, path, "quality")?;
        let fpath = format!("{path}.quality");
        if x < 0.0 {
            return Err(self.err(
                &fpath,
                format!("negative value {n}; SSIM must be in [0, 1]"),
            ));
        }
        if x > 1.0 {
            return Err(self.err(&fpath, format!("value {n} above 1; SSIM must be in [0, 1]")));
        }
        Ok(x)
    }

    fn profile(&self, v: &Value, path: &str) -> Result<Profile, SceneError> {
        let obj = v
            .as_object()
            .ok_or_else(|| self.err(path, "expected an object with size, quality, g, p"))?;
        let params = |key: &str| -> Result<ModelParams, SceneError> {
            let mpath = format!("{path}.{key}");
            let m = self
                .field(obj, path, key)?
                .as_object()
                .ok_or_else(|| self.err(&mpath, "expected an object with k, a, b, m"))?;
            let family = match m.get("g_power") {
                None | Some(Value::Null) => Family::Volume,
                Some(v) => v.as_f64().and_then(Family::from_g_power).ok_or_else(|| {
                    self.err(
                        &format!("{mpath}.g_power"),
                        format!("must be 3 (volume), 2 (surface) or 1.5 (quads), got {v}"),
                    )
                })?,
            };
            // The per-quad term: absent in files written before it existed.
            let c = match m.get("c") {
                None | Some(Value::Null) => 0.0,
                Some(_) => self.number(m, &mpath, "c")?.0,
            };
            Ok(ModelParams {
                k: self.number(m, &mpath, "k")?.0,
                a: self.number(m, &mpath, "a")?.0,
                b: self.number(m, &mpath, "b")?.0,
                c,
                m: self.number(m, &mpath, "m")?.0,
                family,
            })
        };
        let size = params("size")?;
        let quality = params("quality")?;
        let list = |key: &str| -> Result<Vec<u32>, SceneError> {
            let lpath = format!("{path}.{key}");
            let arr = self
                .field(obj, path, key)?
                .as_array()
                .ok_or_else(|| self.err(&lpath, "expected a list of positive integers"))?;
            if arr.is_empty() {
                return Err(self.err(&lpath, "empty list"));
            }
            if arr.len() > MAX_CONFIGS {
                return Err(self.err(
                    &lpath,
                    format!(
                        "{} values; at most {MAX_CONFIGS} configurations are supported",
                        arr.len()
                    ),
                ));
            }
            let mut out = Vec::with_capacity(arr.len());
            // O(log n) per value: a long list must not take quadratic time.
            let mut seen = std::collections::BTreeSet::new();
            for (i, item) in arr.iter().enumerate() {
                let ipath = format!("{lpath}[{i}]");
                let v = item
                    .as_u64()
                    .and_then(|v| u32::try_from(v).ok())
                    .filter(|&v| v > 0)
                    .ok_or_else(|| {
                        self.err(&ipath, format!("must be a positive integer, got {item}"))
                    })?;
                if !seen.insert(v) {
                    return Err(self.err(&ipath, format!("duplicate value {v}")));
                }
                out.push(v);
            }
            Ok(out)
        };
        let g = list("g")?;
        let p = list("p")?;
        if g.len() * p.len() > MAX_CONFIGS {
            return Err(self.err(
                path,
                format!(
                    "{} × {} = {} configurations; at most {MAX_CONFIGS} are supported",
                    g.len(),
                    p.len(),
                    g.len() * p.len()
                ),
            ));
        }
        Ok(Profile {
            size,
            quality,
            g,
            p,
        })
    }

    fn evaluate(
        &self,
        profile: &Profile,
        path: &str,
        geometry: Geometry,
    ) -> Result<Vec<ConfigEntry>, SceneError> {
        let field_err = |e: ProfileError| match e {
            ProfileError::NotFinite { curve, field, .. }
            | ProfileError::ParamOutOfRange { curve, field, .. } => {
                self.err(&format!("{path}.{curve}.{field}"), e.to_string())
            }
            other => self.err(path, other.to_string()),
        };
        let fixed = profile.fixed().map_err(field_err)?;
        let mut out = Vec::with_capacity(profile.g.len() * profile.p.len());
        for &g in &profile.g {
            for &p in &profile.p {
                let at = |curve: &str, e: ProfileError| match e {
                    ProfileError::GridOutOfRange { .. } => {
                        self.err(&format!("{path}.g"), e.to_string())
                    }
                    ProfileError::PatchOutOfRange { .. } => {
                        self.err(&format!("{path}.p"), e.to_string())
                    }
                    other => self.err(&format!("{path}.{curve}"), other.to_string()),
                };
                let size = fixed.size.size(g, p).map_err(|e| at("size", e))?;
                let quality = fixed.quality.quality(g, p).map_err(|e| at("quality", e))?;
                out.push(ConfigEntry {
                    g,
                    p,
                    size,
                    quality: quality.to_f64(),
                    geometry,
                });
            }
        }
        Ok(out)
    }
}

/// `planes`' objects with `mesh`'s profile of the same name added as their
/// mesh profile: one scene whose objects plan over both geometries. Both
/// must be single-profile scenes (as `nerflex profile fit` writes them)
/// with the same object names; each comes with the label its errors name
/// it by (a flag, or a description).
pub fn union(
    (planes, planes_label): (&Scene, &str),
    (mesh, mesh_label): (&Scene, &str),
) -> Result<Scene, String> {
    let profile_of = |o: &SceneObject, flag: &str| -> Result<Profile, String> {
        match (&o.profile, &o.mesh_profile) {
            (Some(p), None) => Ok(p.clone()),
            _ => Err(format!(
                "{flag}: object `{}` is not in single-profile form (one \"profile\", as `nerflex profile fit` writes it); it has {}",
                o.name,
                if o.profile.is_none() && o.mesh_profile.is_none() {
                    "a configuration table"
                } else {
                    "several profiles"
                }
            )),
        }
    };
    let names = |s: &Scene| s.objects.iter().map(|o| o.name.clone()).collect::<Vec<_>>();
    let mut objects = Vec::with_capacity(planes.objects.len());
    for o in &planes.objects {
        let planes_profile = profile_of(o, planes_label)?;
        let m = mesh
            .objects
            .iter()
            .find(|m| m.name == o.name)
            .ok_or_else(|| {
                format!(
                    "{mesh_label} has no object `{}` (it has: {})",
                    o.name,
                    names(mesh).join(", ")
                )
            })?;
        let mesh_profile = profile_of(m, mesh_label)?;
        let mut configs = o.configs.clone();
        configs.extend(m.configs.iter().map(|c| ConfigEntry {
            geometry: Geometry::Mesh,
            ..*c
        }));
        objects.push(SceneObject {
            name: o.name.clone(),
            configs,
            profile: Some(planes_profile),
            mesh_profile: Some(mesh_profile),
        });
    }
    if let Some(extra) = mesh
        .objects
        .iter()
        .find(|m| !planes.objects.iter().any(|o| o.name == m.name))
    {
        return Err(format!(
            "{planes_label} has no object `{}` (it has: {})",
            extra.name,
            names(planes).join(", ")
        ));
    }
    Ok(Scene {
        objects,
        single: planes.single.clone(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        parse(text, "scene.json").unwrap_err().to_string()
    }

    #[test]
    fn table_form() {
        let s = parse(
            r#"{"objects": [{"name": "lego", "note": "extra", "configs": [
                {"g": 128, "p": 17, "size_bytes": 104857600, "quality": 0.951, "psnr": 30.1},
                {"g": 64, "p": 9, "size_bytes": 1.5e7, "quality": 0.9}]}]}"#,
            "scene.json",
        )
        .unwrap();
        assert_eq!(s.objects.len(), 1);
        assert_eq!(s.objects[0].configs[0].size, Bytes(104_857_600));
        assert_eq!(s.objects[0].configs[1].size, Bytes(15_000_000));
        assert_eq!(s.objects[0].configs[0].quality, 0.951);
        assert!(s.single.is_none());
        // Round trip.
        let again = parse(&s.to_json().to_string(), "x").unwrap();
        assert_eq!(again, s);
    }

    #[test]
    fn errors_name_file_and_field() {
        let base = |cfg: &str| format!(r#"{{"objects": [{{"name": "a", "configs": [{cfg}]}}]}}"#);
        assert_eq!(
            err(&base(
                r#"{"g": 1, "p": 1, "size_bytes": -3, "quality": 0.5}"#
            )),
            "scene.json: objects[0].configs[0].size_bytes: negative value -3"
        );
        assert_eq!(
            err(&base(
                r#"{"g": 1, "p": 1, "size_bytes": 3, "quality": 1.5}"#
            )),
            "scene.json: objects[0].configs[0].quality: value 1.5 above 1; SSIM must be in [0, 1]"
        );
        assert_eq!(
            err(&base(
                r#"{"g": 1.5, "p": 1, "size_bytes": 3, "quality": 0.5}"#
            )),
            "scene.json: objects[0].configs[0].g: must be a positive integer, got 1.5"
        );
        assert_eq!(
            err(&base(r#"{"g": 1, "p": 1, "quality": 0.5}"#)),
            "scene.json: objects[0].configs[0].size_bytes: missing"
        );
        assert_eq!(
            err(&base("")),
            "scene.json: objects[0].configs: empty list: an object needs at least one configuration"
        );
        assert_eq!(
            err(r#"{"objects": []}"#),
            "scene.json: objects: empty list: a scene needs at least one object"
        );
        let dup = r#"{"objects": [{"name": "a", "configs": [{"g": 1, "p": 1, "size_bytes": 1, "quality": 0.5}]},
                                   {"name": "a", "configs": [{"g": 1, "p": 1, "size_bytes": 1, "quality": 0.5}]}]}"#;
        assert_eq!(
            err(dup),
            "scene.json: objects[1].name: duplicate name \"a\" (also objects[0])"
        );
        assert!(err("{").starts_with("scene.json: invalid JSON: "));
        assert!(err("[1]").starts_with("scene.json: expected a JSON object"));
        assert_eq!(
            err(r#"{"objects": [{"name": "a"}]}"#),
            "scene.json: objects[0]: needs \"configs\", \"profile\" or \"profiles\""
        );
        assert!(err("{\"objects\": [{\"name\": \"a\", \"configs\": [{\"g\": 1, \"p\": 1, \"size_bytes\": 1e999, \"quality\": 0.5}]}]}")
            .starts_with("scene.json: invalid JSON"));
    }

    #[test]
    fn profile_form_is_evaluated_on_its_grid() {
        let s = parse(
            r#"{"objects": [{"name": "lego", "profile": {
                "size": {"k": 0.5, "a": 0, "b": 0, "m": 1000},
                "quality": {"k": 100, "a": 0, "b": 0, "m": 0.95},
                "g": [2, 4], "p": [1, 3]}}]}"#,
            "scene.json",
        )
        .unwrap();
        let c = &s.objects[0].configs;
        assert_eq!(c.len(), 4);
        // S(2,1) = 0.5·8·1 + 1000 = 1004; Q(2,1) = 0.95 − 100/8 < 0 → 0.
        assert_eq!(
            (c[0].g, c[0].p, c[0].size, c[0].quality),
            (2, 1, Bytes(1004), 0.0)
        );
        // S(4,3) = 0.5·64·9 + 1000 = 1288; Q = 0.95 − 100/576 (to the
        // Q1.31 step of the fixed-point evaluation).
        assert_eq!(c[3].size, Bytes(1288));
        assert!((c[3].quality - (0.95 - 100.0 / 576.0)).abs() < 1e-9);
        let again = parse(&s.to_json().to_string(), "x").unwrap();
        assert_eq!(again, s);
        let bad = r#"{"objects": [{"name": "lego", "profile": {
                "size": {"k": -0.5, "a": 0, "b": 0, "m": 0},
                "quality": {"k": 1, "a": 0, "b": 0, "m": 0.95}, "g": [2], "p": [1]}}]}"#;
        assert_eq!(
            err(bad),
            "scene.json: objects[0].profile.size.k: size k = -0.5 is outside the supported range [0, 1024]"
        );
    }

    #[test]
    fn profile_form_g_power_and_range_errors() {
        let scene = |size: &str, g: &str| {
            format!(
                r#"{{"objects": [{{"name": "o", "profile": {{"size": {size},
                "quality": {{"k": 100, "a": 0, "b": 0, "m": 0.95, "g_power": 2}},
                "g": {g}, "p": [1, 3]}}}}]}}"#
            )
        };
        let s = parse(
            &scene(
                r#"{"k": 0.5, "a": 0, "b": 0, "m": 1000, "g_power": 2}"#,
                "[2, 4]",
            ),
            "scene.json",
        )
        .unwrap();
        let c = &s.objects[0].configs;
        // S(4,3) = 0.5·16·9 + 1000 = 1072; Q(4,3) = 0.95 − 100/144.
        assert_eq!(c[3].size, Bytes(1072));
        assert!((c[3].quality - (0.95 - 100.0 / 144.0)).abs() < 1e-9);
        let prof = s.objects[0].profile.as_ref().unwrap();
        assert_eq!(prof.size.family, Family::Surface);
        assert_eq!(
            prof.size_gradient(4.0, 3.0),
            (2.0 * 0.5 * 4.0 * 9.0, 2.0 * 0.5 * 16.0 * 3.0)
        );
        let again = parse(&s.to_json().to_string(), "x").unwrap();
        assert_eq!(again, s);
        assert_eq!(
            err(&scene(
                r#"{"k": 0.5, "a": 0, "b": 0, "m": 1000, "g_power": 4}"#,
                "[2]"
            )),
            "scene.json: objects[0].profile.size.g_power: must be 3 (volume), 2 (surface) or 1.5 (quads), got 4"
        );
        // The quads family: g_power 1.5 and a per-quad term c, written back
        // as read; S(4,3) = 0.5·4^{3/2}·9 + 2·16 + 1000 = 1068.
        let quads = parse(
            &scene(
                r#"{"k": 0.5, "a": 0, "b": 0, "m": 1000, "g_power": 1.5, "c": 2}"#,
                "[2, 4]",
            ),
            "scene.json",
        )
        .unwrap();
        assert_eq!(quads.objects[0].configs[3].size, Bytes(1068));
        let qprof = quads.objects[0].profile.as_ref().unwrap();
        assert_eq!(qprof.size.family, Family::Quads);
        assert_eq!(
            qprof.size_gradient(4.0, 3.0),
            (
                1.5 * 0.5 * 8.0 * 9.0 / 4.0 + 2.0 * 2.0 * 4.0,
                2.0 * 0.5 * 8.0 * 3.0
            )
        );
        let json = qprof.to_json();
        assert_eq!(
            (json["size"]["g_power"].as_f64(), json["size"]["c"].as_f64()),
            (Some(1.5), Some(2.0))
        );
        // Profiles without the term are written as before it existed.
        assert!(prof.to_json()["size"].get("c").is_none());
        assert_eq!(prof.to_json()["size"]["g_power"], 2);
        assert_eq!(parse(&quads.to_json().to_string(), "x").unwrap(), quads);
        assert_eq!(
            err(&scene(
                r#"{"k": 0.5, "a": 0, "b": 0, "m": 1000, "c": "x"}"#,
                "[2]"
            )),
            "scene.json: objects[0].profile.size.c: expected a number, got \"x\""
        );
        assert_eq!(
            err(&scene(
                r#"{"k": 0.5, "a": 0, "b": 0, "m": 1000, "c": -1}"#,
                "[2]"
            )),
            "scene.json: objects[0].profile.size.c: size c = -1 is outside the supported range [0, 16777216]"
        );
        assert_eq!(
            err(&scene(r#"{"k": 0.5, "a": -3, "b": 0, "m": 1000}"#, "[2]")),
            "scene.json: objects[0].profile.size: at (g 2, p 1) g + a or p + b is outside [0.5, 4096] / [0.5, 256]"
        );
        assert_eq!(
            err(&scene(r#"{"k": 0.5, "a": 0, "b": 0, "m": 1000}"#, "[2000]")),
            "scene.json: objects[0].profile.g: grid g = 2000 is outside 1..=1024"
        );
    }

    #[test]
    fn geometry_absent_means_planes_and_rows_may_be_mesh() {
        let s = parse(
            r#"{"objects": [{"name": "lego", "configs": [
                {"g": 64, "p": 9, "size_bytes": 10, "quality": 0.9},
                {"g": 64, "p": 9, "size_bytes": 8, "quality": 0.92, "geometry": "mesh"},
                {"g": 32, "p": 9, "size_bytes": 4, "quality": 0.8, "geometry": "planes"}]}]}"#,
            "scene.json",
        )
        .unwrap();
        let geo: Vec<Geometry> = s.objects[0].configs.iter().map(|c| c.geometry).collect();
        assert_eq!(geo, [Geometry::Planes, Geometry::Mesh, Geometry::Planes]);
        assert_eq!(s.objects[0].geometries(), Geometry::ALL);
        // Written back: planes rows without the field, mesh rows with it.
        let json = s.to_json();
        let rows = json["objects"][0]["configs"].as_array().unwrap();
        assert!(rows[0].get("geometry").is_none() && rows[2].get("geometry").is_none());
        assert_eq!(rows[1]["geometry"], "mesh");
        assert_eq!(parse(&json.to_string(), "x").unwrap(), s);
        let base = |row: &str| {
            format!(
                r#"{{"objects": [{{"name": "lego", "configs": [
                {{"g": 64, "p": 9, "size_bytes": 10, "quality": 0.9}}, {row}]}}]}}"#
            )
        };
        assert_eq!(
            err(&base(r#"{"g": 64, "p": 9, "size_bytes": 1, "quality": 0.5, "geometry": "meshes"}"#)),
            "scene.json: objects[0].configs[1].geometry: object \"lego\": unknown geometry \"meshes\"; expected planes or mesh"
        );
        assert_eq!(
            err(&base(r#"{"g": 64, "p": 9, "size_bytes": 1, "quality": 0.5, "geometry": 2}"#)),
            "scene.json: objects[0].configs[1].geometry: object \"lego\": expected \"planes\" or \"mesh\", got 2"
        );
        assert_eq!(
            err(&base(r#"{"g": 64, "p": 9, "size_bytes": 1, "quality": 0.5, "geometry": "planes"}"#)),
            "scene.json: objects[0].configs[1]: duplicate configuration (g 64, p 9) (also objects[0].configs[0])"
        );
    }

    const PLANES: &str = r#"{"size": {"k": 0.5, "a": 0, "b": 0, "m": 1000},
        "quality": {"k": 100, "a": 0, "b": 0, "m": 0.95}, "g": [2, 4], "p": [1, 3]}"#;
    const MESH: &str = r#"{"size": {"k": 0.25, "a": 0, "b": 0, "m": 500, "g_power": 2},
        "quality": {"k": 50, "a": 0, "b": 0, "m": 0.9}, "g": [4, 8], "p": [3]}"#;

    #[test]
    fn one_profile_per_geometry() {
        let s = parse(
            &format!(r#"{{"objects": [{{"name": "lego", "profiles": {{"mesh": {MESH}, "planes": {PLANES}}}}}]}}"#),
            "scene.json",
        )
        .unwrap();
        let o = &s.objects[0];
        // The union, planes first: 2 × 2 planes then 2 × 1 mesh.
        let got: Vec<(u32, u32, Geometry)> =
            o.configs.iter().map(|c| (c.g, c.p, c.geometry)).collect();
        assert_eq!(
            got,
            [
                (2, 1, Geometry::Planes),
                (2, 3, Geometry::Planes),
                (4, 1, Geometry::Planes),
                (4, 3, Geometry::Planes),
                (4, 3, Geometry::Mesh),
                (8, 3, Geometry::Mesh),
            ]
        );
        // Mesh S(4,3) = 0.25·16·9 + 500 = 536 bytes.
        assert_eq!(o.configs[4].size, Bytes(536));
        assert!(o.profile_of(Geometry::Planes).is_some());
        assert_eq!(o.profile_of(Geometry::Mesh).unwrap().g, [4, 8]);
        assert_eq!(parse(&s.to_json().to_string(), "x").unwrap(), s);
        // The old single profile is exactly the planes entry of "profiles".
        let old = parse(
            &format!(r#"{{"objects": [{{"name": "lego", "profile": {PLANES}}}]}}"#),
            "scene.json",
        )
        .unwrap();
        let new = parse(
            &format!(r#"{{"objects": [{{"name": "lego", "profiles": {{"planes": {PLANES}}}}}]}}"#),
            "scene.json",
        )
        .unwrap();
        assert_eq!(old, new);
        // A planes-only object is written in the old form.
        assert!(old.to_json()["objects"][0].get("profile").is_some());
        // Mesh only.
        let mesh_only = parse(
            &format!(r#"{{"objects": [{{"name": "lego", "profiles": {{"mesh": {MESH}}}}}]}}"#),
            "scene.json",
        )
        .unwrap();
        assert_eq!(mesh_only.objects[0].geometries(), [Geometry::Mesh]);
        assert!(mesh_only.objects[0].profile.is_none());
        assert_eq!(
            parse(&mesh_only.to_json().to_string(), "x").unwrap(),
            mesh_only
        );
    }

    #[test]
    fn profiles_errors_name_the_object_and_field() {
        assert_eq!(
            err(&format!(r#"{{"objects": [{{"name": "lego", "profiles": {{"meshes": {MESH}}}}}]}}"#)),
            "scene.json: objects[0].profiles.meshes: object \"lego\": unknown geometry \"meshes\"; expected planes or mesh"
        );
        assert_eq!(
            err(r#"{"objects": [{"name": "lego", "profiles": {}}]}"#),
            "scene.json: objects[0].profiles: object \"lego\": no profiles"
        );
        assert_eq!(
            err(&format!(r#"{{"objects": [{{"name": "lego", "profile": {PLANES}, "profiles": {{"mesh": {MESH}}}}}]}}"#)),
            "scene.json: objects[0]: has both \"profile\" and \"profiles\"; give one of \"configs\", \"profile\" or \"profiles\""
        );
        let bad_mesh = MESH.replace(r#""k": 0.25"#, r#""k": -1"#);
        assert_eq!(
            err(&format!(r#"{{"objects": [{{"name": "lego", "profiles": {{"mesh": {bad_mesh}}}}}]}}"#)),
            "scene.json: objects[0].profiles.mesh.size.k: size k = -1 is outside the supported range [0, 1024]"
        );
    }
}

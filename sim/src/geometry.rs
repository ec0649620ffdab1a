//! The bake geometry a configuration is built with, shared by the scene
//! file, the planner and the baker (which converts it into its own
//! `bake::trained::GeometryKind`), so the scene file does not depend on
//! the baker's internals.
//!
//! `planes` (per shell voxel, quads tilted onto the surface; every bake
//! before session 15 and the default everywhere) or `mesh` (one connected
//! mesh, MobileNeRF's topology; `nerflex bake --surface mesh`).

use serde::{Deserialize, Serialize};
use std::fmt;

/// A bake geometry.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Geometry {
    /// Planar quads per shell voxel (the default).
    #[default]
    Planes,
    /// One connected mesh.
    Mesh,
}

impl Geometry {
    /// Every geometry, in the order scene files list them.
    pub const ALL: [Geometry; 2] = [Geometry::Planes, Geometry::Mesh];

    /// The name in JSON and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Geometry::Planes => "planes",
            Geometry::Mesh => "mesh",
        }
    }

    /// The geometry named `s` (exactly as [`Geometry::name`] spells it).
    pub fn parse(s: &str) -> Option<Geometry> {
        Geometry::ALL.into_iter().find(|g| g.name() == s)
    }

    /// Whether this is the default, [`Geometry::Planes`] (JSON leaves it out).
    pub fn is_planes(&self) -> bool {
        *self == Geometry::Planes
    }
}

impl fmt::Display for Geometry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_planes_is_the_default() {
        for g in Geometry::ALL {
            assert_eq!(Geometry::parse(g.name()), Some(g));
            assert_eq!(serde_json::to_value(g).unwrap(), g.name());
        }
        assert_eq!(Geometry::parse("Mesh"), None);
        assert_eq!(Geometry::parse("mesh+planes"), None);
        assert_eq!(Geometry::default(), Geometry::Planes);
        assert!(Geometry::Planes.is_planes() && !Geometry::Mesh.is_planes());
    }
}

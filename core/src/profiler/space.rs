//! An object's configuration space: every pair of a `g` list and a `p` list.

use super::ProfileError;
use crate::mck::MAX_CONFIGS;

/// The configurations `(g, p)` for `g` in `grids` and `p` in `patches`,
/// `g`-major: index `i` is `(grids[i / patches.len()], patches[i % patches.len()])`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfigSpace<'a> {
    grids: &'a [u32],
    patches: &'a [u32],
}

impl<'a> ConfigSpace<'a> {
    /// A space of `grids.len() × patches.len()` configurations; both lists
    /// non-empty and at most [`MAX_CONFIGS`] configurations (the solver's
    /// limit).
    pub fn new(grids: &'a [u32], patches: &'a [u32]) -> Result<ConfigSpace<'a>, ProfileError> {
        let bad = ProfileError::BadSpace {
            grids: grids.len(),
            patches: patches.len(),
        };
        match grids.len().checked_mul(patches.len()) {
            Some(n) if n > 0 && n <= MAX_CONFIGS => Ok(ConfigSpace { grids, patches }),
            _ => Err(bad),
        }
    }

    /// The `g` values.
    pub fn grids(&self) -> &'a [u32] {
        self.grids
    }

    /// The `p` values.
    pub fn patches(&self) -> &'a [u32] {
        self.patches
    }

    /// Number of configurations (at most [`MAX_CONFIGS`], never zero).
    pub fn len(&self) -> usize {
        // Checked in `new`.
        self.grids.len().saturating_mul(self.patches.len())
    }

    /// Always `false`: a space has at least one configuration.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The configuration at `index`, if any.
    pub fn get(&self, index: usize) -> Option<(u32, u32)> {
        let n = self.patches.len();
        let g = self.grids.get(index.checked_div(n)?)?;
        let p = self.patches.get(index.checked_rem(n)?)?;
        Some((*g, *p))
    }

    /// The index of `(g, p)`, if it is in the space.
    pub fn index_of(&self, g: u32, p: u32) -> Option<usize> {
        let gi = self.grids.iter().position(|&x| x == g)?;
        let pi = self.patches.iter().position(|&x| x == p)?;
        gi.checked_mul(self.patches.len())?.checked_add(pi)
    }

    /// Every configuration, `g`-major.
    pub fn iter(&self) -> impl Iterator<Item = (u32, u32)> + 'a {
        let patches = self.patches;
        self.grids
            .iter()
            .flat_map(move |&g| patches.iter().map(move |&p| (g, p)))
    }
}

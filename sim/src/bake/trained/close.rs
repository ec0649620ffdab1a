//! Closing the planes' texel opacity: a transparent texel most of whose
//! patch neighbours are opaque becomes opaque.
//!
//! A plane's texel is opaque where the field's surface crosses the texel's
//! line inside the voxel. On fine structure (lego's tracks and studs) that
//! test leaves pinholes and slivers a texel or two wide, under a pixel at
//! 800 px. Training pixels see them at their centres only, rarely, but the
//! renderer's 2 × 2 subsamples find them, and composited over white they
//! are white specks: 12.6 % of lego's (128, 17) held-out squared error
//! (`docs/baking.md`, "Session 18"). Closing runs before the hull carve,
//! which then empties what the closing put outside a silhouette, and the
//! visibility round removes what the photos show to be wrong.

use rayon::prelude::*;

/// Most patch neighbours a texel has.
pub const NEIGHBOURS: u32 = 8;

/// Makes every transparent texel with at least `min_opaque` opaque texels
/// among its 8 neighbours in its own `p × p` patch opaque (one pass, judged
/// on the opacity as it was, so the result does not depend on the order).
/// `opacity` holds `p²` texels per quad, row-major; 0 does nothing. Returns
/// the number of texels made opaque.
pub fn close(opacity: &mut [bool], p: u32, min_opaque: u32) -> u64 {
    let pu = p as usize;
    let p2 = pu * pu;
    if min_opaque == 0 || p2 == 0 {
        return 0;
    }
    opacity
        .par_chunks_mut(p2)
        .map_init(Vec::new, |old, patch| {
            old.clear();
            old.extend_from_slice(patch);
            let opaque = |x: usize, y: usize| old.get(y * pu + x).copied().unwrap_or(false);
            let mut n = 0u64;
            for y in 0..pu {
                for x in 0..pu {
                    if opaque(x, y) || patch.len() < p2 {
                        continue;
                    }
                    let mut count = 0;
                    for ny in y.saturating_sub(1)..=(y + 1).min(pu - 1) {
                        for nx in x.saturating_sub(1)..=(x + 1).min(pu - 1) {
                            count += u32::from((nx, ny) != (x, y) && opaque(nx, ny));
                        }
                    }
                    if count >= min_opaque {
                        patch[y * pu + x] = true;
                        n += 1;
                    }
                }
            }
            n
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A patch from rows of `#` (opaque) and `.`.
    fn patch(rows: &[&str]) -> Vec<bool> {
        rows.iter()
            .flat_map(|r| r.chars().map(|c| c == '#'))
            .collect()
    }

    #[test]
    fn a_pinhole_closes_and_an_edge_stays() {
        let mut o = patch(&["#####", "#####", "##.##", "#####", "....."]);
        // The pinhole has 8 opaque neighbours; the bottom row's texels have
        // at most 3 (the row above).
        assert_eq!(close(&mut o, 5, 4), 1);
        assert_eq!(o, patch(&["#####", "#####", "#####", "#####", "....."]));
        // At 3 the bottom row's inner texels (3 opaque neighbours) close
        // too, its corners (2) do not.
        let mut o = patch(&["#####", "#####", "##.##", "#####", "....."]);
        assert_eq!(close(&mut o, 5, 3), 4);
        assert_eq!(o, patch(&["#####", "#####", "#####", "#####", ".###."]));
    }

    #[test]
    fn one_pass_judged_on_the_old_opacity_and_patches_apart() {
        // Two 3 × 3 patches: a diagonal in the first; the second empty.
        let mut o = patch(&["#..", ".#.", "..#"]);
        o.extend(patch(&["...", "...", "..."]));
        // The diagonal's side neighbours have 2 opaque neighbours, the two
        // corners 1. At 2 the four sides close; the corners would have 3
        // once their sides closed, but the pass reads the old opacity.
        let mut two = o.clone();
        assert_eq!(close(&mut two, 3, 2), 4);
        assert_eq!(&two[..9], &patch(&["##.", "###", ".##"])[..]);
        // Nothing spills into the second patch.
        assert!(two[9..].iter().all(|&t| !t));
        // At 1 the corners close too; at 3 nothing does.
        let mut one = o.clone();
        assert_eq!(close(&mut one, 3, 1), 6);
        assert!(one[..9].iter().all(|&t| t) && one[9..].iter().all(|&t| !t));
        let mut three = o.clone();
        assert_eq!(close(&mut three, 3, 3), 0);
        // Off, and more than any texel has: nothing.
        let mut off = o.clone();
        assert_eq!(close(&mut off, 3, 0), 0);
        assert_eq!(close(&mut off, 3, NEIGHBOURS + 1), 0);
        assert_eq!(off, o);
    }
}

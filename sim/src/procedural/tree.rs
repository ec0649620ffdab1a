//! The branching skeleton of the `tree` object: tapered capsules grown
//! recursively from a fixed seed, with foliage clumps at the tips, evaluated
//! through a bounding-sphere hierarchy so a distance query only visits the
//! branches near the point.

use super::sdf::{smin, tapered_capsule};
use glam::{Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::OnceLock;

/// Blend width between branches (local units).
const BRANCH_BLEND: f32 = 0.03;
/// Blend width between foliage clumps.
const LEAF_BLEND: f32 = 0.04;

struct Node {
    a: Vec3,
    b: Vec3,
    ra: f32,
    rb: f32,
    foliage: Option<(Vec3, f32)>,
    bound_c: Vec3,
    bound_r: f32,
    children: Vec<usize>,
}

/// The grown tree.
pub struct Tree {
    nodes: Vec<Node>,
    /// Candidate lists of a uniform grid over the tree (see [`Tree::eval`]).
    grid: CellGrid,
    /// Axis-aligned bounds of wood and foliage (before leaf displacement).
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

/// The tree, grown on first use (always the same).
pub fn tree() -> &'static Tree {
    static TREE: OnceLock<Tree> = OnceLock::new();
    TREE.get_or_init(grow)
}

const MAX_DEPTH: u32 = 5;

fn grow() -> Tree {
    let mut rng = ChaCha8Rng::seed_from_u64(0x7ee5);
    let mut nodes = Vec::new();
    let trunk_dir = Vec3::new(0.08, -0.04, 1.0).normalize();
    branch(
        &mut nodes,
        &mut rng,
        0,
        Vec3::new(0.0, 0.0, -0.66),
        trunk_dir,
        0.52,
        0.095,
    );
    fit_unit_cube(&mut nodes);
    finish_bounds(&mut nodes, 0);
    let (mut min, mut max) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for n in &nodes {
        for (c, r) in [(n.a, n.ra), (n.b, n.rb)].into_iter().chain(n.foliage) {
            min = min.min(c - Vec3::splat(r));
            max = max.max(c + Vec3::splat(r));
        }
    }
    let grid = CellGrid::build(&nodes, min - Vec3::splat(0.1), max + Vec3::splat(0.1));
    Tree {
        nodes,
        grid,
        min,
        max,
    }
}

/// Cells per axis of the candidate grid.
const CELLS: usize = 32;

/// For every cell of a uniform grid, the branches and the foliage clumps
/// that can change the smooth minimum anywhere in the cell: a primitive
/// whose distance lower bound over the cell (value at the centre minus the
/// half diagonal) exceeds the smallest upper bound of any primitive (value
/// at the centre plus the half diagonal) by more than the blend width
/// cannot, so it is left out and the result is unchanged.
struct CellGrid {
    min: Vec3,
    cell: Vec3,
    /// Per cell: start in `items`, branch count, clump count.
    cells: Vec<(u32, u16, u16)>,
    items: Vec<u16>,
}

impl CellGrid {
    fn build(nodes: &[Node], min: Vec3, max: Vec3) -> Self {
        let cell = (max - min) / CELLS as f32;
        let half_diag = 0.5 * cell.length();
        let mut cells = Vec::with_capacity(CELLS * CELLS * CELLS);
        let mut items = Vec::new();
        for k in 0..CELLS {
            for j in 0..CELLS {
                for i in 0..CELLS {
                    let c = min + cell * Vec3::new(i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5);
                    let wood: Vec<f32> = nodes
                        .iter()
                        .map(|n| tapered_capsule(c, n.a, n.b, n.ra, n.rb))
                        .collect();
                    let leaf: Vec<Option<f32>> = nodes
                        .iter()
                        .map(|n| n.foliage.map(|(fc, r)| (c - fc).length() - r))
                        .collect();
                    let wmin = wood.iter().fold(f32::MAX, |a, &b| a.min(b)) + half_diag;
                    let lmin = leaf.iter().flatten().fold(f32::MAX, |a, &b| a.min(b)) + half_diag;
                    let start = items.len() as u32;
                    let mut nw = 0u16;
                    for (idx, &d) in wood.iter().enumerate() {
                        if d - half_diag <= wmin + BRANCH_BLEND {
                            items.push(idx as u16);
                            nw += 1;
                        }
                    }
                    let mut nl = 0u16;
                    for (idx, d) in leaf.iter().enumerate() {
                        if let Some(d) = d {
                            if d - half_diag <= lmin + LEAF_BLEND {
                                items.push(idx as u16);
                                nl += 1;
                            }
                        }
                    }
                    cells.push((start, nw, nl));
                }
            }
        }
        Self {
            min,
            cell,
            cells,
            items,
        }
    }

    #[inline]
    fn lookup(&self, p: Vec3) -> Option<(&[u16], &[u16])> {
        let q = (p - self.min) / self.cell;
        if q.min_element() < 0.0 || q.max_element() >= CELLS as f32 {
            return None;
        }
        let (i, j, k) = (q.x as usize, q.y as usize, q.z as usize);
        let &(start, nw, nl) = self.cells.get(i + CELLS * (j + CELLS * k))?;
        let (s, w, l) = (start as usize, nw as usize, nl as usize);
        Some((self.items.get(s..s + w)?, self.items.get(s + w..s + w + l)?))
    }
}

fn branch(
    nodes: &mut Vec<Node>,
    rng: &mut ChaCha8Rng,
    depth: u32,
    a: Vec3,
    dir: Vec3,
    len: f32,
    ra: f32,
) -> usize {
    let b = a + dir * len;
    let rb = ra * 0.7;
    let id = nodes.len();
    let foliage = (depth + 2 >= MAX_DEPTH).then(|| {
        let r = 0.08 + 0.02 * (depth + 2 - MAX_DEPTH) as f32;
        (b + dir * 0.05, r + rng.random_range(0.0..0.04))
    });
    nodes.push(Node {
        a,
        b,
        ra,
        rb,
        foliage,
        bound_c: Vec3::ZERO,
        bound_r: 0.0,
        children: Vec::new(),
    });
    if depth < MAX_DEPTH {
        let n = if depth == 0 {
            3
        } else {
            rng.random_range(2..=3)
        };
        let phase: f32 = rng.random_range(0.0..std::f32::consts::TAU);
        // Any vector not parallel to dir gives a perpendicular axis family.
        let side = if dir.z.abs() < 0.9 { Vec3::Z } else { Vec3::X };
        let perp = dir.cross(side).normalize();
        for k in 0..n {
            let az =
                phase + k as f32 * std::f32::consts::TAU / n as f32 + rng.random_range(-0.3..0.3);
            let tilt = rng.random_range(0.45..0.75f32);
            let axis = Quat::from_axis_angle(dir, az) * perp;
            let mut d = Quat::from_axis_angle(axis, tilt) * dir;
            // Branches reach up and out, as trees do toward light.
            d = (d + Vec3::new(0.0, 0.0, 0.25)).normalize();
            let l = len * rng.random_range(0.68..0.8);
            let c = branch(nodes, rng, depth + 1, b, d, l, rb);
            nodes[id].children.push(c);
        }
    }
    id
}

/// Shrinks the grown tree about its trunk base so wood and foliage stay
/// inside x, y, z ≤ 0.95 (the unit-cube convention with a margin).
fn fit_unit_cube(nodes: &mut [Node]) {
    let base = nodes.first().map_or(Vec3::ZERO, |n| n.a);
    let mut s = 1.0f32;
    for n in nodes.iter() {
        for (c, r) in [(n.a, n.ra), (n.b, n.rb)].into_iter().chain(n.foliage) {
            let d = c - base;
            for (v, room) in [
                (d.x.abs() + r, 0.95),
                (d.y.abs() + r, 0.95),
                (d.z + r, 0.95 - base.z),
            ] {
                if v > room {
                    s = s.min(room / v);
                }
            }
        }
    }
    for n in nodes.iter_mut() {
        n.a = base + (n.a - base) * s;
        n.b = base + (n.b - base) * s;
        n.ra *= s;
        n.rb *= s;
        n.foliage = n.foliage.map(|(c, r)| (base + (c - base) * s, r * s));
    }
}

/// Bounding sphere of each subtree, children first.
fn finish_bounds(nodes: &mut [Node], id: usize) {
    let children = nodes[id].children.clone();
    for &c in &children {
        finish_bounds(nodes, c);
    }
    let n = &nodes[id];
    let c = 0.5 * (n.a + n.b);
    let mut r = 0.5 * (n.b - n.a).length() + n.ra.max(n.rb) + BRANCH_BLEND;
    if let Some((fc, fr)) = n.foliage {
        r = r.max((fc - c).length() + fr + LEAF_BLEND);
    }
    for &ch in &children {
        r = r.max((nodes[ch].bound_c - c).length() + nodes[ch].bound_r);
    }
    nodes[id].bound_c = c;
    nodes[id].bound_r = r;
}

impl Tree {
    /// Distances to the wood and to the foliage clumps.
    pub fn eval(&self, p: Vec3) -> (f32, f32) {
        let (mut wood, mut leaf) = (f32::MAX, f32::MAX);
        if let Some((ws, ls)) = self.grid.lookup(p) {
            for &i in ws {
                let n = &self.nodes[i as usize];
                wood = smin(wood, tapered_capsule(p, n.a, n.b, n.ra, n.rb), BRANCH_BLEND);
            }
            for &i in ls {
                if let Some((c, r)) = self.nodes[i as usize].foliage {
                    leaf = smin(leaf, (p - c).length() - r, LEAF_BLEND);
                }
            }
            return (wood, leaf);
        }
        // Outside the grid: walk the bounding-sphere hierarchy.
        let mut stack = [0usize; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top]];
            // A subtree farther than the current distance plus the blend
            // width cannot change the smooth minimum.
            if (p - n.bound_c).length() - n.bound_r > wood.min(leaf) + LEAF_BLEND {
                continue;
            }
            wood = smin(wood, tapered_capsule(p, n.a, n.b, n.ra, n.rb), BRANCH_BLEND);
            if let Some((c, r)) = n.foliage {
                leaf = smin(leaf, (p - c).length() - r, LEAF_BLEND);
            }
            for &c in &n.children {
                if top < stack.len() {
                    stack[top] = c;
                    top += 1;
                }
            }
        }
        (wood, leaf)
    }

    /// Number of branch segments.
    #[cfg(test)]
    pub fn branches(&self) -> usize {
        self.nodes.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn culled_evaluation_matches_brute_force_near_the_surface() {
        let t = tree();
        assert!(t.branches() > 20);
        let brute = |p: Vec3| {
            let (mut w, mut l) = (f32::MAX, f32::MAX);
            for n in &t.nodes {
                w = smin(w, tapered_capsule(p, n.a, n.b, n.ra, n.rb), BRANCH_BLEND);
                if let Some((c, r)) = n.foliage {
                    l = smin(l, (p - c).length() - r, LEAF_BLEND);
                }
            }
            w.min(l)
        };
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..2000 {
            let p = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let (w, l) = t.eval(p);
            let fast = w.min(l);
            let slow = brute(p);
            // Culling only drops far blends: the sign and near distances agree.
            if slow.abs() < 0.05 {
                assert!((fast - slow).abs() < 0.02, "{p} {fast} {slow}");
            }
            if slow.abs() > 1e-3 {
                assert_eq!(fast < 0.0, slow < 0.0, "{p} {fast} {slow}");
            }
        }
    }
}

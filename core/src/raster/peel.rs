//! Two layers in one draw: the front sample of every pixel and the one a
//! second, peeling pass ([`TileRenderer::draw_behind`]) would find behind
//! it, without that second pass.
//!
//! The peel keeps the nearest fragment that is more than [`PEEL_MARGIN`]
//! behind the *final* front sample and not of its quad. While drawing, the
//! front can still move nearer, and then fragments that were too close to
//! the old front may pass behind the new one. Fragments behind the margin
//! never need keeping beyond the best of them: a nearer front only widens
//! what passes. So each pixel keeps the front, the best fragment that
//! passes so far, and one fragment within the margin (or of the front's
//! quad). A pixel that would need two of those marks the tile undecided,
//! and [`TwoLayers::resolve`] then draws the back layer again by peeling,
//! so the result is always the two-pass one, bit for bit (ties go to the
//! earlier-drawn fragment, as the depth test's strict `>` does).

use super::{
    for_each_triangle, peels, AlphaTest, GPixel, ScreenQuad, TileRenderer, TileStats, View,
};

/// Where in the draw order a kept fragment came (ties go to the earlier).
type Order = u32;

/// Fragments kept per pixel within the margin of the front (coplanar
/// overlaps of grown quads put two or three there).
const NEAR: usize = 3;

const EMPTY: GPixel = GPixel {
    inv_w: 0.0,
    part: 0,
    tx: 0,
    ty: 0,
    quad: 0,
};

/// A tile's front layer and the layer behind it, drawn in one pass.
#[derive(Debug, Clone)]
pub struct TwoLayers<const W: usize, const H: usize> {
    front: TileRenderer<W, H>,
    back: TileRenderer<W, H>,
    /// A fragment that does not pass the peel behind the current front
    /// (within the margin, or of its quad) but may behind a nearer one.
    near: [[[GPixel; NEAR]; W]; H],
    /// Draw order of the front, back and near fragments.
    order: [[[Order; 2 + NEAR]; W]; H],
    drawn: Order,
    undecided: bool,
}

impl<const W: usize, const H: usize> Default for TwoLayers<W, H> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize, const H: usize> TwoLayers<W, H> {
    /// Empty layers.
    pub const fn new() -> Self {
        Self {
            front: TileRenderer::new(),
            back: TileRenderer::new(),
            near: [[[EMPTY; NEAR]; W]; H],
            order: [[[0; 2 + NEAR]; W]; H],
            drawn: 0,
            undecided: false,
        }
    }

    /// Starts the tile whose top-left pixel is `(x0, y0)` (clipped to the image).
    pub fn begin(&mut self, view: &View, x0: u32, y0: u32) {
        self.front.begin(view, x0, y0);
        self.back.begin(view, x0, y0);
        for row in self.near.iter_mut() {
            for p in row.iter_mut().flatten() {
                p.inv_w = 0.0;
            }
        }
        self.drawn = 0;
        self.undecided = false;
    }

    /// The front layer: what [`TileRenderer::draw`] of the same quads gives
    /// (its counters too).
    pub fn front(&self) -> &TileRenderer<W, H> {
        &self.front
    }

    /// The layer behind it: the samples [`TileRenderer::draw_behind`] gives,
    /// once [`TwoLayers::resolve`] has run (its counters are not kept).
    pub fn back(&self) -> &TileRenderer<W, H> {
        &self.back
    }

    /// Whether some pixel kept too little to decide its back layer in one
    /// pass (then [`TwoLayers::resolve`] redraws it).
    pub fn undecided(&self) -> bool {
        self.undecided
    }

    /// Rasterizes a projected quad into both layers (depth + alpha test).
    pub fn draw<A: AlphaTest + ?Sized>(&mut self, sq: &ScreenQuad, atlas: &A) {
        let seq = self.drawn;
        if seq == Order::MAX {
            self.undecided = true;
        }
        self.drawn = seq.saturating_add(1);
        self.draw_at(sq, atlas, seq);
    }

    /// Rasterizes a projected quad that comes `seq`-th in the draw order
    /// (distinct per quad), drawn now in any order: equal depths go to the
    /// lower `seq`, so once [`TwoLayers::resolve`] has run the layers do
    /// not depend on the order of the calls (whether it had to redraw, and
    /// the front's counters, do). Near quads first lets most hidden
    /// fragments skip their alpha test. Don't mix with [`TwoLayers::draw`]
    /// in one tile, and give [`TwoLayers::resolve`] the quads in `seq`
    /// order.
    pub fn draw_at<A: AlphaTest + ?Sized>(&mut self, sq: &ScreenQuad, atlas: &A, seq: u32) {
        if !self.front.touches(sq) {
            return;
        }
        let rect = self.front.rect();
        let Self {
            front,
            back,
            near,
            order,
            undecided,
            ..
        } = self;
        let (fg, bg) = (&mut front.g, &mut back.g);
        // The back layer's alpha tests are not the front's work.
        let mut other = TileStats::default();
        for_each_triangle(sq, &mut front.stats, |tri, stats| {
            tri.scan(rect, stats, |ry, rx, iw, l, stats| {
                let (Some(f), Some(b), Some(n), Some(o)) = (
                    fg.get_mut(ry).and_then(|r| r.get_mut(rx)),
                    bg.get_mut(ry).and_then(|r| r.get_mut(rx)),
                    near.get_mut(ry).and_then(|r| r.get_mut(rx)),
                    order.get_mut(ry).and_then(|r| r.get_mut(rx)),
                ) else {
                    return;
                };
                // Nearer, or as near and earlier in the draw order (never
                // both with in-order draws; `iw > 0` when `f` is empty).
                if iw > f.inv_w || (iw == f.inv_w && seq < o[0] && iw > 0.0) {
                    let Some(px) = tri.fragment(sq, atlas, iw, l, stats) else {
                        return;
                    };
                    // A new front: the old one and the near fragments are
                    // judged against it; the back one still passes (a
                    // nearer front only widens the peel) unless it shares
                    // the new front's quad id.
                    if b.inv_w > 0.0 && b.quad == sq.id {
                        *undecided = true;
                    }
                    let (old_front, old_seq) = (*f, o[0]);
                    *f = px;
                    o[0] = seq;
                    let mut place =
                        |y: GPixel,
                         oy: Order,
                         n: &mut [GPixel; NEAR],
                         o: &mut [Order; 2 + NEAR]| {
                            if y.inv_w <= 0.0 {
                                return;
                            }
                            if peels(&px, y.quad, y.inv_w) {
                                if y.inv_w > b.inv_w || (y.inv_w == b.inv_w && oy < o[1]) {
                                    *b = y;
                                    o[1] = oy;
                                }
                            } else if !keep_near(n, o, y, oy) {
                                *undecided = true;
                            }
                        };
                    // Near fragments fill their slots from the first, so an
                    // empty first slot means none (the common case).
                    if n[0].inv_w > 0.0 {
                        let (old_near, old_order) = (*n, *o);
                        for y in n.iter_mut() {
                            y.inv_w = 0.0;
                        }
                        for (&y, &oy) in old_near.iter().zip(&old_order[2..]) {
                            place(y, oy, n, o);
                        }
                    }
                    place(old_front, old_seq, n, o);
                } else if iw.is_nan() || iw <= 0.0 {
                    // Never kept by either pass (also NaN).
                } else if peels(f, sq.id, iw) {
                    if iw > b.inv_w || (iw == b.inv_w && seq < o[1]) {
                        if let Some(px) = tri.fragment(sq, atlas, iw, l, &mut other) {
                            *b = px;
                            o[1] = seq;
                        }
                    }
                } else if let Some(px) = tri.fragment(sq, atlas, iw, l, &mut other) {
                    if !keep_near(n, o, px, seq) {
                        *undecided = true;
                    }
                }
            });
        });
    }

    /// Whether drawing `sq` now would change neither layer: every pixel of
    /// its box in this tile already has a sample behind the front nearer
    /// than `nearest` ([`TileRenderer::hides`] of the layer behind), so
    /// all of its fragments would pass behind both. Quads drawn nearest
    /// first can then be skipped: the layers stay those of drawing them
    /// (only the front's counters and [`TwoLayers::undecided`] may
    /// differ).
    pub fn hides(&self, sq: &ScreenQuad, nearest: f32) -> bool {
        self.back.hides(sq, nearest)
    }

    /// Makes the back layer exact where one pass could not decide it: if
    /// the tile is undecided, draws `quads` (the tile's, in the same order)
    /// again behind the front. Returns whether it did.
    pub fn resolve<'q, A: AlphaTest + ?Sized + 'q>(
        &mut self,
        quads: impl IntoIterator<Item = (&'q ScreenQuad, &'q A)>,
    ) -> bool {
        if !self.undecided {
            return false;
        }
        let (x0, y0, w, h) = self.front.rect();
        self.back.restart(x0, y0, w, h);
        for (sq, atlas) in quads {
            self.back.draw_behind(sq, atlas, &self.front);
        }
        self.undecided = false;
        true
    }
}

/// Keeps `y` (drawn `oy`-th) in the first free near slot; `false` when all
/// are taken.
#[inline(always)]
fn keep_near(n: &mut [GPixel; NEAR], o: &mut [Order; 2 + NEAR], y: GPixel, oy: Order) -> bool {
    match n
        .iter_mut()
        .zip(o[2..].iter_mut())
        .find(|(slot, _)| slot.inv_w <= 0.0)
    {
        Some((slot, so)) => {
            *slot = y;
            *so = oy;
            true
        }
        None => false,
    }
}

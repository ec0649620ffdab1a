//! Packing one p×p texel cell per quad into RGBA8 atlas pages.
//!
//! A page holds at most [`MAX_PAGE_TEXELS`]² texels, so ⌊4096/p⌋² cells
//! (MobileNeRF's p = 17 gives 240 × 240 cells in 4080² texels of a 4096²
//! page). Cells are filled row by row in quad order. Full pages are
//! ⌊4096/p⌋·p texels square; the last page is only as large as its cells
//! need (near-square), so small objects do not pay for a whole 4096² page
//! and the byte counts grow smoothly with the number of quads.
//!
//! A quad's corners sit on the centres of its cell's corner texels, so with
//! nearest filtering the p texels along an edge show as p − 2 full texels
//! and two half texels: texel (x, y) of the cell is the quad point
//! (x/(p−1), y/(p−1)).

use image::RgbaImage;

/// Largest page edge, texels (MobileNeRF's and most phones' texture limit).
pub const MAX_PAGE_TEXELS: u32 = 4096;

/// Where the cells of a range of quads sit in one page.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PageLayout {
    /// The first quad (global index) on this page.
    pub first_quad: usize,
    /// Quads on this page.
    pub quads: usize,
    /// Cells per row.
    pub cols: u32,
    /// Rows of cells.
    pub rows: u32,
}

impl PageLayout {
    /// The quads (global indices) in row `row` of cells, with their
    /// column: how a pass that fills a page one row of cells at a time
    /// walks it.
    pub fn row_quads(&self, row: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let cols = self.cols as usize;
        (0..cols)
            .map(move |col| (col, row * cols + col))
            .take_while(|&(_, local)| local < self.quads)
            .map(|(col, local)| (col, self.first_quad + local))
    }
}

/// The cell layout of every quad.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AtlasLayout {
    /// Texels per cell edge (p).
    pub patch: u32,
    /// The pages, in order.
    pub pages: Vec<PageLayout>,
}

/// The cell of one quad: page and texel position of its top-left texel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cell {
    /// Page index.
    pub page: usize,
    /// Texel column of the cell's left edge.
    pub x: u32,
    /// Texel row of the cell's top edge.
    pub y: u32,
}

impl AtlasLayout {
    /// Cells per row (and rows) of a full page at patch `p`.
    pub fn max_cells_per_edge(p: u32) -> u32 {
        (MAX_PAGE_TEXELS / p.max(1)).max(1)
    }

    /// The layout of `quads` cells of `p`×`p` texels.
    pub fn new(quads: usize, p: u32) -> Self {
        let edge = Self::max_cells_per_edge(p) as usize;
        let per_page = edge * edge;
        let mut pages = Vec::new();
        let mut first = 0;
        while first < quads {
            let n = (quads - first).min(per_page);
            let (cols, rows) = if n == per_page {
                (edge, edge)
            } else {
                let cols = ((n as f64).sqrt().ceil() as usize).clamp(1, edge);
                (cols, n.div_ceil(cols))
            };
            pages.push(PageLayout {
                first_quad: first,
                quads: n,
                cols: cols as u32,
                rows: rows as u32,
            });
            first += n;
        }
        Self { patch: p, pages }
    }

    /// Page size in texels (width, height).
    pub fn page_size(&self, page: usize) -> (u32, u32) {
        self.pages
            .get(page)
            .map_or((0, 0), |l| (l.cols * self.patch, l.rows * self.patch))
    }

    /// The cell of quad `q`, if it is laid out.
    pub fn cell(&self, q: usize) -> Option<Cell> {
        let page = self.pages.partition_point(|l| l.first_quad + l.quads <= q);
        let l = self.pages.get(page)?;
        let c = (q - l.first_quad) as u32;
        Some(Cell {
            page,
            x: (c % l.cols) * self.patch,
            y: (c / l.cols) * self.patch,
        })
    }

    /// Total quads laid out.
    pub fn quads(&self) -> usize {
        self.pages.iter().map(|l| l.quads).sum()
    }
}

/// One page of both feature atlases.
#[derive(Debug, Clone)]
pub struct AtlasPage {
    /// Features 0..3 (R, G, B, A as stored in `shapeN.pngfeat0.png`).
    pub feat0: RgbaImage,
    /// Features 4..7 (`shapeN.pngfeat1.png`).
    pub feat1: RgbaImage,
}

/// The two feature atlases of a baked object.
#[derive(Debug, Clone)]
pub struct Atlas {
    /// Where each quad's cell is.
    pub layout: AtlasLayout,
    /// The pages, one per shape file of the export.
    pub pages: Vec<AtlasPage>,
}

impl Atlas {
    /// GPU-resident bytes: both atlases' pages decoded as RGBA8.
    pub fn gpu_bytes(&self) -> u64 {
        self.pages
            .iter()
            .map(|p| {
                4 * (u64::from(p.feat0.width()) * u64::from(p.feat0.height())
                    + u64::from(p.feat1.width()) * u64::from(p.feat1.height()))
            })
            .sum()
    }
}

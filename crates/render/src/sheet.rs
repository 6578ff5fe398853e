//! Contact sheets: pictures tiled into one image, row by row (`render`'s camera sheets,
//! `cameras --preview`, augment's sheet of sampled views).

use image::imageops::{self, FilterType};
use image::{Rgb, RgbImage};

/// How a contact sheet lays its tiles out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SheetLayout {
    /// Tiles per row.
    pub columns: u32,
    /// Square cell size in pixels, each tile resized to it; `None`: cells the size of
    /// the first tile, tiles drawn as they are.
    pub tile: Option<u32>,
    /// Pixels between cells and around the sheet.
    pub gap: u32,
    /// Colour of the gaps and of empty cells.
    pub background: [u8; 3],
}

/// Tiles `tiles` into one image; `None` when there are none.
pub fn contact_sheet(tiles: &[RgbImage], layout: SheetLayout) -> Option<RgbImage> {
    let first = tiles.first()?;
    let (w, h) = layout
        .tile
        .map_or((first.width(), first.height()), |t| (t, t));
    let (cols, gap) = (layout.columns.max(1), layout.gap);
    let rows = (tiles.len() as u32).div_ceil(cols);
    let mut sheet = RgbImage::from_pixel(
        cols * (w + gap) + gap,
        rows * (h + gap) + gap,
        Rgb(layout.background),
    );
    for (i, tile) in tiles.iter().enumerate() {
        let (c, r) = (i as u32 % cols, i as u32 / cols);
        let (x, y) = (
            i64::from(gap + c * (w + gap)),
            i64::from(gap + r * (h + gap)),
        );
        match layout.tile {
            Some(t) => {
                let resized = imageops::resize(tile, t, t, FilterType::Triangle);
                imageops::replace(&mut sheet, &resized, x, y);
            }
            None => imageops::replace(&mut sheet, tile, x, y),
        }
    }
    Some(sheet)
}

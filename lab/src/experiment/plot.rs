//! PNG plots (plotters' bitmap backend) with a font compiled into the binary, so that a
//! machine or container without fonts draws the same figures.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use graybox::error::{Error, Result};

/// DejaVu Sans cut to the characters the plots use (`scripts/subset-font.sh`).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans-subset.ttf");
pub const FAMILY: &str = "sans-serif";

/// matplotlib's first colours (the paper's figures use them): blue, orange, green, red, purple.
pub const COLORS: [RGBColor; 5] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x94, 0x67, 0xbd),
];
pub const GRAY: RGBColor = RGBColor(0x99, 0x99, 0x99);

pub type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
pub type DrawResult = std::result::Result<(), Box<dyn std::error::Error>>;

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        if plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_err() {
            panic!("the compiled-in font is a valid TrueType font");
        }
    });
}

/// Draws a `width`×`height` PNG at `path` on a white background. Drawn to a temporary file
/// and renamed: a reader never sees half a figure.
pub fn png(
    path: &Path,
    (width, height): (u32, u32),
    draw: impl FnOnce(&Area) -> DrawResult,
) -> Result<()> {
    register_font();
    let name = path
        .file_name()
        .map_or_else(Default::default, |n| n.to_string_lossy().into_owned());
    let tmp = path.with_file_name(format!(".{name}.partial.png"));
    let drawn: DrawResult = (|| {
        let root = BitMapBackend::new(&tmp, (width, height)).into_drawing_area();
        root.fill(&WHITE)?;
        draw(&root)?;
        root.present()?;
        Ok(())
    })();
    drawn.map_err(|e| Error::Internal(format!("drawing {}: {e}", path.display())))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        Error::Io(std::io::Error::new(
            e.kind(),
            format!("{}: {e}", path.display()),
        ))
    })
}

/// A chart of f64 against f64 on a PNG's drawing area.
pub type Chart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// A small panel of an angle against time: [0, `t_end`] s × [`lo`, `hi`] rad, captioned.
pub fn angle_panel<'a, 'b: 'a>(
    area: &'a Area<'b>,
    caption: &str,
    t_end: f64,
    (lo, hi): (f64, f64),
) -> std::result::Result<Chart<'a, 'b>, Box<dyn std::error::Error>> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption, font(15))
        .margin(6)
        .x_label_area_size(28)
        .y_label_area_size(48)
        .build_cartesian_2d(0f64..t_end, lo..hi)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("s")
        .y_desc("rad")
        .label_style(font(12))
        .axis_desc_style(font(12))
        .draw()?;
    Ok(chart)
}

/// A text style in the plots' font.
pub fn font(size: u32) -> TextStyle<'static> {
    (FAMILY, size).into_font().into()
}

//! Pixel geometry of one cell of a figure: margins, label areas, font sizes, tick counts, and
//! a title that fits the cell.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::axes::{Axis, AxisSpec};

/// Pixel sizes shared by all panel kinds of a cell, so stacked panels align.
pub(super) struct Layout {
    pub(super) scale: f64,
    pub(super) margin: u32,
    pub(super) x_area: u32,
    pub(super) y_area: u32,
    pub(super) plot_w: f64,
    pub(super) plot_h: f64,
}

impl Layout {
    pub(super) fn for_cell((w, h): (u32, u32)) -> Self {
        let scale = (f64::from(h) / 380.0)
            .min(f64::from(w) / 560.0)
            .clamp(0.7, 2.5);
        let px = |v: f64| (v * scale).round() as u32;
        let (margin, x_area, y_area) = (px(12.0), px(48.0), px(80.0));
        let caption = px(30.0);
        Layout {
            scale,
            margin,
            x_area,
            y_area,
            plot_w: (f64::from(w) - f64::from(y_area + 3 * margin)).max(10.0),
            plot_h: (f64::from(h) - f64::from(x_area + caption + 2 * margin)).max(10.0),
        }
    }

    pub(super) fn px(&self, v: f64) -> u32 {
        ((v * self.scale).round() as u32).max(1)
    }

    pub(super) fn font(&self, size: f64, style: FontStyle) -> TextStyle<'static> {
        TextStyle::from(FontDesc::new(
            FontFamily::SansSerif,
            size * self.scale,
            style,
        ))
    }

    /// The title font: 18 pt (times the cell scale), shrunk so that the whole title fits
    /// between the cell's margins (plotters centres a caption and clips what overflows, so a
    /// long title would lose both ends). Never below 9 pt, where text stays legible.
    pub(super) fn title_font<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        title: &str,
    ) -> TextStyle<'static> {
        let full = 18.0;
        let available = f64::from(area.dim_in_pixel().0.saturating_sub(2 * self.margin));
        let width = area
            .estimate_text_size(title, &self.font(full, FontStyle::Bold))
            .map_or(0.0, |(w, _)| f64::from(w));
        let size = if width > available && width > 0.0 {
            (full * available / width).max(9.0)
        } else {
            full
        };
        self.font(size, FontStyle::Bold)
    }

    pub(super) fn x_ticks(&self) -> usize {
        ((self.plot_w / (90.0 * self.scale)) as usize).clamp(2, 10)
    }

    pub(super) fn y_ticks(&self) -> usize {
        ((self.plot_h / (45.0 * self.scale)) as usize).clamp(2, 8)
    }

    pub(super) fn chart<'a, DB: DrawingBackend>(
        &self,
        area: &'a DrawingArea<DB, Shift>,
        title: &str,
        x: &AxisSpec,
        y: &AxisSpec,
    ) -> Result<ChartContext<'a, DB, Cartesian2d<Axis, Axis>>, String> {
        let mut builder = ChartBuilder::on(area);
        builder
            .margin(self.margin)
            .margin_right(self.margin * 2)
            .x_label_area_size(self.x_area)
            .y_label_area_size(self.y_area);
        if !title.is_empty() {
            builder.caption(title, self.title_font(area, title));
        }
        builder
            .build_cartesian_2d(x.coord(), y.coord())
            .map_err(|e| e.to_string())
    }

    pub(super) fn mesh<DB: DrawingBackend>(
        &self,
        chart: &mut ChartContext<'_, DB, Cartesian2d<Axis, Axis>>,
        x: &AxisSpec,
        y: &AxisSpec,
        x_label: &str,
        y_label: &str,
        grid: bool,
    ) -> Result<(), String> {
        let x_fmt = |v: &f64| x.label(*v);
        let y_fmt = |v: &f64| y.label(*v);
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(x_label)
            .y_desc(y_label)
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .label_style(self.font(13.0, FontStyle::Normal))
            .axis_desc_style(self.font(15.0, FontStyle::Normal))
            .bold_line_style(RGBColor(215, 215, 215))
            .light_line_style(RGBColor(238, 238, 238));
        if !grid {
            mesh.disable_mesh();
        }
        mesh.draw().map_err(|e| e.to_string())?;
        // Frame around the plot area.
        chart
            .plotting_area()
            .draw(&Rectangle::new(
                [(x.lo, y.lo), (x.hi, y.hi)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A title far wider than its cell at 18 pt is shrunk until it fits between the margins
    /// (within one pixel of rounding), and a short one keeps the full size.
    #[test]
    fn long_titles_fit_their_cell() {
        let (w, h) = (500u32, 350u32);
        let mut rgb = vec![0u8; (w * h * 3) as usize];
        let area = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        super::super::draw::register_fonts();
        let layout = Layout::for_cell((w, h));
        let available = w - 2 * layout.margin;
        let long = "Sweep: max |K~ - K+| against local inversion time (base p = 3, levels 4..8, \
                    1024 uniform samples)";
        let font = layout.title_font(&area, long);
        let (width, _) = area.estimate_text_size(long, &font).unwrap();
        assert!(width <= available + 1, "title {width} px in {available} px");
        let full = area
            .estimate_text_size(long, &layout.font(18.0, FontStyle::Bold))
            .unwrap()
            .0;
        assert!(full > available, "the test title must overflow at 18 pt");
        let short = layout.title_font(&area, "K^T");
        assert_eq!(
            short.font.get_size(),
            layout.font(18.0, FontStyle::Bold).font.get_size()
        );
    }
}

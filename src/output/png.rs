//! The mesh seen from above as a PNG: the svg picture's layout, rasterised with tiny-skia and
//! lettered with embedded-graphics' built-in bitmap fonts, so no system font is needed.
//!
//! The picture is drawn whole (the HTTP layer encodes on the blocking pool). Triangles are
//! filled without anti-aliasing: two triangles sharing an edge then cover each pixel centre
//! exactly once between them, where anti-aliased fills would leave a faint seam of background.
//! Triangles of one colour are filled as one path, so a 10^6-triangle mesh costs one fill
//! per colour, not one per triangle.

use super::picture::{self, BACKGROUND, INK, Layout, TextMetrics};
use super::{Encoded, Options, Part};
use crate::result::RunResult;
use embedded_graphics::mono_font::iso_8859_1 as fonts;
use embedded_graphics::mono_font::{MonoFont, MonoTextStyle};
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::{DrawTarget, Drawable, OriginDimensions, Point, RgbColor, Size};
use embedded_graphics::text::{Baseline, Text};
use std::sync::Arc;
use tiny_skia::{FillRule, Paint, PathBuilder, Pixmap, PremultipliedColorU8, Rect, Stroke, Transform};

/// The picture of `result`, `options.size` pixels wide.
pub fn encode(result: &Arc<RunResult>, options: &Options) -> Encoded {
    Encoded::new(vec![Part::Bytes(render(result, options.size))])
}

/// The PNG file of `result`, `width` pixels wide.
fn render(result: &RunResult, width: u32) -> Vec<u8> {
    let width = width.max(1);
    let (font, scale) = font_for(width);
    let text = metrics(font, scale);
    let layout = Layout::new(result, f64::from(width), text);
    let height = layout.height as u32;
    let mut pixmap = Pixmap::new(width, height).expect("the layout has a positive size");
    pixmap.fill(colour(BACKGROUND, 255));

    fill_triangles(&mut pixmap, result, &layout);
    draw_edges(&mut pixmap, result, &layout);
    draw_field_lines(&mut pixmap, result, &layout);
    draw_outlines(&mut pixmap, &layout);
    draw_bar(&mut pixmap, &layout, layout.shading.range);
    draw_ticks(&mut pixmap, &layout);

    let style = MonoTextStyle::new(font, Rgb888::new(INK[0], INK[1], INK[2]));
    let mut canvas = Canvas { pixmap: &mut pixmap, left: 0, top: 0, scale };
    // Region names in white on a dark halo: the name in ink one pixel off each way, then on top.
    let white = MonoTextStyle::new(font, Rgb888::new(255, 255, 255));
    for (name, left, top) in &layout.region_names {
        for (dx, dy) in [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0)] {
            canvas.write(name, left + dx, top + dy, style);
        }
        canvas.write(name, *left, *top, white);
    }
    for (label, left, top) in layout.labels.iter().chain(&layout.tick_labels) {
        canvas.write(label, *left, *top, style);
    }
    for (i, line) in layout.lines.iter().enumerate() {
        let left = (layout.width - text.width(line)) / 2.0;
        canvas.write(line, left.max(0.0), layout.text_top + i as f64 * layout.line_height, style);
    }
    encode_png(&pixmap)
}

/// The fonts to pick from, smallest first (Latin-1, for the `·` of the stats line).
const FONTS: [&MonoFont<'static>; 8] = [
    &fonts::FONT_4X6,
    &fonts::FONT_5X8,
    &fonts::FONT_6X10,
    &fonts::FONT_7X13,
    &fonts::FONT_8X13,
    &fonts::FONT_9X15,
    &fonts::FONT_9X18,
    &fonts::FONT_10X20,
];

/// A font and integer magnification whose glyphs are about 1/48 of the picture's width tall:
/// 20 pixels on the default 1024, the largest font doubled on 2048.
fn font_for(width: u32) -> (&'static MonoFont<'static>, u32) {
    let target = width / 48;
    let largest = FONTS[FONTS.len() - 1];
    let height = largest.character_size.height;
    if target >= 2 * height {
        return (largest, target / height);
    }
    let font = FONTS.iter().rev().find(|f| f.character_size.height <= target).unwrap_or(&FONTS[0]);
    (font, 1)
}

fn metrics(font: &MonoFont<'_>, scale: u32) -> TextMetrics {
    let advance = font.character_size.width + font.character_spacing;
    let height = f64::from(font.character_size.height * scale);
    TextMetrics {
        char_width: f64::from(advance * scale),
        char_height: height,
        line_height: (height * 1.3).round(),
    }
}

fn colour([r, g, b]: [u8; 3], alpha: u8) -> tiny_skia::Color {
    tiny_skia::Color::from_rgba8(r, g, b, alpha)
}

fn fill_triangles(pixmap: &mut Pixmap, result: &RunResult, layout: &Layout) {
    let corners: Vec<(f32, f32)> = result
        .vertices
        .iter()
        .map(|v| {
            let (x, y) = layout.to_picture(v.x, v.y);
            (x as f32, y as f32)
        })
        .collect();
    // Sorted by colour, then by id, so each colour is one path and the order is fixed.
    let mut order: Vec<(u32, u32)> = (0..result.triangles.len())
        .map(|t| {
            let [r, g, b] = layout.shading.colour(result, t);
            (u32::from_be_bytes([0, r, g, b]), t as u32)
        })
        .collect();
    order.sort_unstable();
    let mut paint = Paint { anti_alias: false, ..Paint::default() };
    for group in order.chunk_by(|a, b| a.0 == b.0) {
        let mut path = PathBuilder::with_capacity(4 * group.len(), 4 * group.len());
        for &(_, t) in group {
            let [a, b, c] = result.triangles[t as usize].map(|v| corners[v as usize]);
            path.move_to(a.0, a.1);
            path.line_to(b.0, b.1);
            path.line_to(c.0, c.1);
            path.close();
        }
        let [_, r, g, b] = group[0].0.to_be_bytes();
        paint.set_color(colour([r, g, b], 255));
        if let Some(path) = path.finish() {
            pixmap.fill_path(&path, &paint, FillRule::Winding, Transform::identity(), None);
        }
    }
}

fn draw_edges(pixmap: &mut Pixmap, result: &RunResult, layout: &Layout) {
    let opacity = layout.edge_opacity(result.triangles.len());
    if opacity <= 0.0 {
        return;
    }
    let bounds = layout.bounds;
    let mut path = PathBuilder::new();
    for t in 0..result.triangles.len() {
        for (p, q) in picture::owned_edges(result, bounds, t) {
            let [p, q] = [p, q].map(|v| {
                let v = result.vertices[v as usize];
                layout.to_picture(v.x, v.y)
            });
            path.move_to(p.0 as f32, p.1 as f32);
            path.line_to(q.0 as f32, q.1 as f32);
        }
    }
    let Some(path) = path.finish() else { return };
    let paint = line_paint(INK, opacity);
    let stroke = Stroke { width: layout.line_width as f32, ..Stroke::default() };
    pixmap.stroke_path(&path, &paint, &stroke, Transform::identity(), None);
}

/// The field lines of a magnetostatic solution, as one anti-aliased path.
fn draw_field_lines(pixmap: &mut Pixmap, result: &RunResult, layout: &Layout) {
    let mut path = PathBuilder::new();
    for t in 0..result.triangles.len() {
        layout.shading.field_lines(result, t, |p, q| {
            let [p, q] = [p, q].map(|[x, y]| layout.to_picture(x, y));
            path.move_to(p.0 as f32, p.1 as f32);
            path.line_to(q.0 as f32, q.1 as f32);
        });
    }
    let Some(path) = path.finish() else { return };
    let stroke = Stroke { width: layout.field_line_width() as f32, ..Stroke::default() };
    pixmap.stroke_path(
        &path,
        &line_paint(INK, picture::FIELD_LINE_OPACITY),
        &stroke,
        Transform::identity(),
        None,
    );
}

/// The regions' outlines, in white over the field.
fn draw_outlines(pixmap: &mut Pixmap, layout: &Layout) {
    let mut path = PathBuilder::new();
    for &[p, q] in &layout.outlines {
        path.move_to(p.0 as f32, p.1 as f32);
        path.line_to(q.0 as f32, q.1 as f32);
    }
    let Some(path) = path.finish() else { return };
    let stroke = Stroke { width: layout.field_line_width() as f32, ..Stroke::default() };
    let paint = line_paint(BACKGROUND, picture::OUTLINE_OPACITY);
    pixmap.stroke_path(&path, &paint, &stroke, Transform::identity(), None);
}

/// The colour bar, max at the top, one row of pixels at a time, in a thin frame.
fn draw_bar(pixmap: &mut Pixmap, layout: &Layout, (lo, hi): (f64, f64)) {
    let bar = layout.bar;
    let mut paint = Paint { anti_alias: false, ..Paint::default() };
    let rows = bar.height as u32;
    for row in 0..rows {
        let t = 1.0 - (f64::from(row) + 0.5) / f64::from(rows);
        paint.set_color(colour(super::colour::of(lo + t * (hi - lo), lo, hi), 255));
        let rect = Rect::from_xywh(bar.left as f32, (bar.top + f64::from(row)) as f32, bar.width as f32, 1.0);
        if let Some(rect) = rect {
            pixmap.fill_rect(rect, &paint, Transform::identity(), None);
        }
    }
    // Half a line outside the bar, so a one-pixel frame sits on whole pixels.
    let half = layout.line_width / 2.0;
    let frame = Rect::from_xywh(
        (bar.left - half) as f32,
        (bar.top - half) as f32,
        (bar.width + 2.0 * half) as f32,
        (bar.height + 2.0 * half) as f32,
    );
    if let Some(frame) = frame {
        let paint = line_paint(INK, 1.0);
        let stroke = Stroke { width: layout.line_width as f32, ..Stroke::default() };
        pixmap.stroke_path(&PathBuilder::from_rect(frame), &paint, &stroke, Transform::identity(), None);
    }
}

/// The axes' tick marks.
fn draw_ticks(pixmap: &mut Pixmap, layout: &Layout) {
    let mut path = PathBuilder::new();
    for &[x1, y1, x2, y2] in &layout.ticks {
        path.move_to(x1 as f32, y1 as f32);
        path.line_to(x2 as f32, y2 as f32);
    }
    let Some(path) = path.finish() else { return };
    let stroke = Stroke { width: layout.line_width as f32, ..Stroke::default() };
    pixmap.stroke_path(&path, &line_paint(INK, 1.0), &stroke, Transform::identity(), None);
}

/// Anti-aliased paint of `rgb` at `opacity`, for lines.
fn line_paint(rgb: [u8; 3], opacity: f64) -> Paint<'static> {
    let mut paint = Paint::default();
    paint.set_color(colour(rgb, (opacity * 255.0).round() as u8));
    paint
}

/// The pixmap as an 8-bit RGB PNG: every pixel is opaque, so an alpha channel would be waste.
fn encode_png(pixmap: &Pixmap) -> Vec<u8> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, pixmap.width(), pixmap.height());
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().expect("writing to a Vec does not fail");
    let mut stream = writer.stream_writer().expect("writing to a Vec does not fail");
    let mut row = Vec::with_capacity(3 * pixmap.width() as usize);
    for pixels in pixmap.pixels().chunks_exact(pixmap.width() as usize) {
        row.clear();
        // Opaque, so the premultiplied values are the colour itself.
        row.extend(pixels.iter().flat_map(|p| [p.red(), p.green(), p.blue()]));
        std::io::Write::write_all(&mut stream, &row).expect("writing to a Vec does not fail");
    }
    stream.finish().expect("every row was written");
    drop(writer);
    out
}

/// Where embedded-graphics draws text: glyph pixels become `scale`² blocks of the pixmap.
struct Canvas<'a> {
    pixmap: &'a mut Pixmap,
    left: i32,
    top: i32,
    scale: u32,
}

impl Canvas<'_> {
    /// Writes `text` with its top-left corner at (left, top) in pixels.
    fn write(&mut self, text: &str, left: f64, top: f64, style: MonoTextStyle<'_, Rgb888>) {
        (self.left, self.top) = (left.round() as i32, top.round() as i32);
        let _ = Text::with_baseline(text, Point::zero(), style, Baseline::Top).draw(self);
    }
}

impl OriginDimensions for Canvas<'_> {
    fn size(&self) -> Size {
        Size::new(self.pixmap.width() / self.scale, self.pixmap.height() / self.scale)
    }
}

impl DrawTarget for Canvas<'_> {
    type Color = Rgb888;
    type Error = std::convert::Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Self::Error>
    where
        I: IntoIterator<Item = embedded_graphics::Pixel<Rgb888>>,
    {
        let (width, height) = (self.pixmap.width() as i64, self.pixmap.height() as i64);
        let scale = i64::from(self.scale);
        for embedded_graphics::Pixel(point, c) in pixels {
            let value = PremultipliedColorU8::from_rgba(c.r(), c.g(), c.b(), 255).expect("opaque is valid");
            let x0 = i64::from(self.left) + i64::from(point.x) * scale;
            let y0 = i64::from(self.top) + i64::from(point.y) * scale;
            for y in (y0..y0 + scale).filter(|y| (0..height).contains(y)) {
                for x in (x0..x0 + scale).filter(|x| (0..width).contains(x)) {
                    self.pixmap.pixels_mut()[(y * width + x) as usize] = value;
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::colour;
    use crate::refine::Criterion;
    use crate::result::testing::{magnetic, sample, with_potential};

    /// A decoded picture: width, height and RGB bytes.
    struct Decoded {
        width: u32,
        height: u32,
        rgb: Vec<u8>,
    }

    impl Decoded {
        fn at(&self, x: f64, y: f64) -> [u8; 3] {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
        }
    }

    fn decode(bytes: &[u8]) -> Decoded {
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.color_type, info.bit_depth), (png::ColorType::Rgb, png::BitDepth::Eight));
        buf.truncate(info.buffer_size());
        Decoded { width: info.width, height: info.height, rgb: buf }
    }

    fn close(a: [u8; 3], b: [u8; 3], tolerance: u8) -> bool {
        a.iter().zip(&b).all(|(x, y)| x.abs_diff(*y) <= tolerance)
    }

    fn picture(result: &RunResult, size: u32) -> (Decoded, Layout) {
        let options = Options { size, ..Options::default() };
        let bytes = encode(&Arc::new(result.clone()), &options).to_vec();
        let (font, scale) = font_for(size);
        (decode(&bytes), Layout::new(result, f64::from(size), metrics(font, scale)))
    }

    #[test]
    fn the_picture_is_as_wide_as_asked_and_as_tall_as_its_layout() {
        let result = sample(100, Criterion::Error);
        for size in [16, 300, 1024] {
            let (image, layout) = picture(&result, size);
            assert_eq!((image.width, image.height), (size, layout.height as u32));
            // [-1, 2] × [0, 1] is three times as wide as tall: the picture is wider than tall.
            assert!(image.height < image.width || size < 100, "{size}: {}", image.height);
        }
    }

    #[test]
    fn a_point_inside_a_triangle_has_that_triangles_colour() {
        let result = sample(40, Criterion::Variation);
        let (image, layout) = picture(&result, 600);
        let [x0, x1, y0, y1] = result.bounds();
        let (lo, hi) = result.z_range();
        let area = |[a, b, c]: [u32; 3]| {
            let [a, b, c] = [a, b, c].map(|v| result.vertices[v as usize]);
            ((b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y)) / 2.0
        };
        // The three largest triangles, at their centroids, mapped by hand with y upward.
        let mut by_area: Vec<usize> = (0..result.triangles.len()).collect();
        by_area.sort_by(|&a, &b| area(result.triangles[b]).total_cmp(&area(result.triangles[a])));
        for &t in &by_area[..3] {
            let corners = result.triangles[t].map(|v| result.vertices[v as usize]);
            let (cx, cy) = (
                corners.iter().map(|v| v.x).sum::<f64>() / 3.0,
                corners.iter().map(|v| v.y).sum::<f64>() / 3.0,
            );
            let px = layout.plot.left + (cx - x0) / (x1 - x0) * layout.plot.width;
            let py = layout.plot.bottom() - (cy - y0) / (y1 - y0) * layout.plot.height;
            let z = corners.iter().map(|v| v.z).sum::<f64>() / 3.0;
            let (got, want) = (image.at(px, py), colour::of(z, lo, hi));
            assert!(close(got, want, 2), "triangle {t} at ({px}, {py}): {got:?}, want {want:?}");
        }
    }

    #[test]
    fn the_fills_leave_no_seams_between_triangles() {
        // Dense enough that no edges are drawn: every pixel of the plot is some triangle's.
        let result = sample(2000, Criterion::Error);
        let (image, layout) = picture(&result, 200);
        assert_eq!(layout.edge_opacity(result.triangles.len()), 0.0);
        let scale: Vec<[u8; 3]> = (0..=1024).map(|i| colour::of(f64::from(i), 0.0, 1024.0)).collect();
        let plot = layout.plot;
        for y in (plot.top.ceil() as u32)..(plot.bottom().floor() as u32) {
            for x in (plot.left.ceil() as u32)..(plot.right().floor() as u32) {
                let got = image.at(f64::from(x), f64::from(y));
                assert!(scale.iter().any(|&c| close(got, c, 3)), "({x}, {y}) is {got:?}, not on the scale");
            }
        }
    }

    #[test]
    fn outside_the_plot_is_background() {
        let result = sample(100, Criterion::Error);
        let (image, layout) = picture(&result, 400);
        for (x, y) in [
            (1.0, 1.0),
            (layout.plot.left - 3.0, layout.plot.top + 10.0),
            (layout.plot.left + 5.0, layout.plot.bottom() + 3.0),
        ] {
            assert_eq!(image.at(x, y), BACKGROUND, "at ({x}, {y})");
        }
        assert_eq!(image.at(f64::from(image.width) - 1.0, f64::from(image.height) - 1.0), BACKGROUND);
    }

    #[test]
    fn the_stats_line_is_written_in_dark_pixels_under_the_plot() {
        let result = sample(100, Criterion::Error);
        let (image, layout) = picture(&result, 1024);
        let dark = |y0: f64, y1: f64| {
            let mut n = 0;
            for y in y0 as u32..y1 as u32 {
                for x in 0..image.width {
                    n += usize::from(image.at(f64::from(x), f64::from(y)).iter().all(|&c| c < 80));
                }
            }
            n
        };
        let text_bottom = layout.text_top + layout.line_height * layout.lines.len() as f64;
        assert!(dark(layout.text_top, text_bottom) > 500, "{}", dark(layout.text_top, text_bottom));
        // Between the plot and the stats line: the ticks and their labels, then nothing.
        let labels_top = layout.plot.bottom() + 1.0;
        let labels_bottom = layout.tick_labels.iter().map(|l| l.2 + layout.line_height).fold(0.0, f64::max);
        assert!(dark(labels_top, labels_bottom) > 50, "the x axis's labels");
        assert_eq!(dark(labels_bottom, layout.text_top), 0);
    }

    #[test]
    fn the_bar_runs_from_the_top_colour_to_the_bottom_colour() {
        let result = sample(100, Criterion::Error);
        let (image, layout) = picture(&result, 800);
        let (lo, hi) = result.z_range();
        let x = layout.bar.left + layout.bar.width / 2.0;
        assert!(close(image.at(x, layout.bar.top + 1.0), colour::of(hi, lo, hi), 6));
        assert!(close(image.at(x, layout.bar.bottom() - 2.0), colour::of(lo, lo, hi), 6));
    }

    #[test]
    fn field_lines_are_dark_lines_where_a_takes_their_levels() {
        // A = x on a solved mesh: the field lines are the verticals x = level. Without the
        // region's outline and name, which the picture would draw over them.
        let mut result = with_potential(magnetic(3000), |x, _| x);
        result.fields.retain(|f| f.name != "region");
        let (image, layout) = picture(&result, 300);
        // The same picture without field lines, to compare with.
        let mut plain = Pixmap::new(image.width, image.height).unwrap();
        fill_triangles(&mut plain, &result, &layout);
        draw_edges(&mut plain, &result, &layout);
        let plain =
            Decoded { width: image.width, height: image.height, rgb: decode(&encode_png(&plain)).rgb };
        let levels = &layout.shading.levels;
        assert_eq!(levels.len(), 20);
        let brightness = |c: [u8; 3]| c.iter().map(|&v| f64::from(v)).sum::<f64>();
        for y in [0.13, 0.37, 0.52, 0.91] {
            let row = layout.to_picture(0.0, y).1;
            for pair in levels.windows(2) {
                let (x, next) = (layout.to_picture(pair[0], y).0, layout.to_picture(pair[1], y).0);
                let darkened = (x.floor() as i32 - 1..=x.ceil() as i32 + 1)
                    .map(|c| {
                        brightness(image.at(f64::from(c), row)) / brightness(plain.at(f64::from(c), row))
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(darkened < 0.75, "no line at ({}, {y}): {darkened}", pair[0]);
                let between = (x + next) / 2.0;
                assert_eq!(image.at(between, row), plain.at(between, row), "a line at ({between}, {y})");
            }
        }
    }

    #[test]
    fn fonts_grow_with_the_picture() {
        assert_eq!(font_for(1024).0.character_size.height, 20);
        let (font, scale) = font_for(2048);
        assert_eq!((font.character_size.height, scale), (20, 2));
        assert_eq!(font_for(16).0.character_size.height, 6);
        assert!(font_for(512).0.character_size.height < 20);
    }
}

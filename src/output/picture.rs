//! What the two pictures (svg, png) share: where the plot, the colour bar and the text go,
//! the text itself, each triangle's colour, the field lines, the regions' outlines and names,
//! and which triangle draws which edge.
//!
//! A result is coloured by the magnitude of its main field per triangle, with the contours of z
//! drawn over it when that field's lines follow them: a magnetostatic solution by |B|, with
//! A's contours as field lines, as FEMM draws one. A mesh, or a Poisson solution, has no main
//! field and is coloured by z.
//!
//! ```text
//!  ┌──────────────────────────────────────────┐
//!  │    1 ┤┌────────────────────────┐ ┌─┐ max  │
//!  │      ││ the mesh from above,   │ │ │      │
//!  │  0.5 ┤│ north up, to scale     │ │ │      │
//!  │    0 ┤└────────────────────────┘ └─┘ min  │
//!  │       ┬    ┬    ┬    ┬    ┬    ┬          │
//!  │       0   0.2  0.4  0.6  0.8   1          │
//!  │  10000 vertices · 19681 triangles ·      │
//!  └──────────────────────────────────────────┘
//! ```
//! Lengths are in picture units: pixels for png, view-box units for svg.

use super::{colour, contour};
use crate::geom::predicates::signed_area_x2;
use crate::result::{Lines, Location, RunResult, Summary};
use std::collections::{BTreeMap, HashMap};

/// A rectangle on the picture, y downward.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Frame {
    pub left: f64,
    pub top: f64,
    pub width: f64,
    pub height: f64,
}

impl Frame {
    pub fn right(&self) -> f64 {
        self.left + self.width
    }

    pub fn bottom(&self) -> f64 {
        self.top + self.height
    }
}

/// The size of the monospace text a renderer draws, in picture units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TextMetrics {
    /// Advance of one character.
    pub char_width: f64,
    /// Height of a glyph cell.
    pub char_height: f64,
    /// Distance between the tops of two lines.
    pub line_height: f64,
}

impl TextMetrics {
    /// How wide `text` is written.
    pub fn width(&self, text: &str) -> f64 {
        text.chars().count() as f64 * self.char_width
    }
}

/// Where everything goes on a picture `width` units wide.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Layout {
    pub width: f64,
    pub height: f64,
    /// The domain's rectangle: its aspect ratio is the domain's.
    pub plot: Frame,
    /// The colour bar, max at the top.
    pub bar: Frame,
    /// The colour bar's labels: text, left and top.
    pub labels: [(String, f64, f64); 2],
    /// The axes' tick marks, from the plot's edge outward: x1, y1, x2, y2.
    pub ticks: Vec<[f64; 4]>,
    /// The ticks' labels: text, left and top; x's under the plot, y's to its left.
    pub tick_labels: Vec<(String, f64, f64)>,
    /// The stats line, wrapped to the width, and the top of its first line.
    pub lines: Vec<String>,
    pub text_top: f64,
    pub line_height: f64,
    /// Width of an edge.
    pub line_width: f64,
    /// x0, x1, y0, y1 of the domain (`result.bounds()`, or the unit square for no mesh).
    pub bounds: [f64; 4],
    /// What colours the triangles and the bar, and the field lines' levels.
    pub shading: Shading,
    /// The regions' sides, as pieces between picture points (none without regions).
    pub outlines: Vec<[(f64, f64); 2]>,
    /// Each region's name (`region i` when it has none) and the top left of where it is
    /// written: inside the box of its triangles, at that box's top left.
    pub region_names: Vec<(String, f64, f64)>,
    scale: f64,
}

/// How many field lines a magnetostatic picture draws (FEMM's default is 19).
const FIELD_LINES: usize = 20;

/// A |B| range narrower than this fraction of its top is one value, coloured mid-scale.
const FLAT: f64 = 1e-9;

/// The |B| scale stops at the value this fraction of the domain's area lies under. B grows
/// without bound at iron's re-entrant corners, and a scale up to the largest triangle's |B|
/// would leave the rest of the picture in its darkest colour.
const SCALE_AREA: f64 = 0.99;

/// What a picture colours its triangles by, and which contours of z it draws.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Shading {
    /// Each triangle's magnitude of the result's main field (|B| in tesla for a magnetostatic
    /// solution), with the legend's words for it; without one a triangle takes the mean of its
    /// corners' z.
    coloured: Option<(Vec<f64>, String)>,
    /// The ends of the colour scale: the smallest coloured value, and the largest (for a field,
    /// the value `SCALE_AREA` of the area lies under).
    pub range: (f64, f64),
    /// The largest coloured value: above the scale when the scale stops short of it.
    max: f64,
    /// The values of z whose contours are the main field's lines (none unless it has lines).
    pub levels: Vec<f64>,
    /// The legend's words for the lines' spacing: their name, z's unit and z's name.
    lines: Option<Lines>,
    /// Metres per unit of x, for lines that follow x·z: their spacing is then in SI units
    /// whatever unit the request's lengths are in.
    metres: f64,
}

impl Shading {
    /// How `result` is coloured.
    pub fn of(result: &RunResult) -> Self {
        let Some(field) = result.main_field().filter(|f| f.location == Location::Cell) else {
            let range = result.z_range();
            return Self {
                coloured: None,
                range,
                max: range.1,
                levels: Vec::new(),
                lines: None,
                metres: 1.0,
            };
        };
        let b: Vec<f64> = (0..field.len()).map(|t| field.magnitude(t)).collect();
        let areas: Vec<f64> = result.triangles.iter().map(|&t| area(result, t)).collect();
        let low = b.iter().copied().fold(f64::INFINITY, f64::min);
        let max = b.iter().copied().fold(0.0, f64::max);
        let mut range = (low.min(max), weighted_quantile(&b, &areas, SCALE_AREA));
        // A uniform field's gradients differ in their last bits; spread over the whole scale,
        // that rounding would paint noise.
        if range.1 - range.0 <= FLAT * range.1 {
            range.0 = range.1;
        }
        let metres = match &result.stats {
            Summary::Solution(s) => 1.0 / s.unit.map_or(1.0, |u| u.per_metre()),
            Summary::Mesh(_) => 1.0,
        };
        let levels = match &field.lines {
            Some(lines) => {
                let (lo, hi) = (result.vertices.iter().map(|v| contoured(lines, metres, v)))
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), z| (lo.min(z), hi.max(z)));
                contour::levels(lo, hi, FIELD_LINES)
            }
            None => Vec::new(),
        };
        let legend = format!("colour |{}| in {}", field.name, field.unit);
        Self { coloured: Some((b, legend)), range, max, levels, lines: field.lines.clone(), metres }
    }

    /// The colour of triangle `t` of `result`.
    pub fn colour(&self, result: &RunResult, t: usize) -> [u8; 3] {
        let value = match &self.coloured {
            Some((b, _)) => b[t],
            None => result.triangles[t].iter().map(|&v| result.vertices[v as usize].z).sum::<f64>() / 3.0,
        };
        colour::of(value, self.range.0, self.range.1)
    }

    /// What the colours and lines stand for, for the stats line (nothing for z).
    fn legend(&self) -> Vec<String> {
        let mut legend = Vec::new();
        if let Some((_, words)) = &self.coloured {
            legend.push(words.clone());
        }
        if self.max > self.range.1 {
            legend.push(format!("max {} above the bar", short(self.max)));
        }
        if let (Some(lines), [first, second, ..]) = (&self.lines, &self.levels[..]) {
            legend.push(format!(
                "{} every {} {} of {}",
                lines.name,
                short(second - first),
                lines.z_unit,
                lines.z
            ));
        }
        legend
    }

    /// Calls `piece` with the ends of each field line's piece in triangle `t` of `result`.
    pub fn field_lines(&self, result: &RunResult, t: usize, piece: impl FnMut([f64; 2], [f64; 2])) {
        if self.levels.is_empty() {
            return;
        }
        let Some(lines) = &self.lines else { return };
        let corners = result.triangles[t].map(|v| {
            let p = result.vertices[v as usize];
            (v, [p.x, p.y, contoured(lines, self.metres, &p)])
        });
        contour::pieces(corners, &self.levels, piece);
    }
}

/// The value at `v` whose contours `lines` follow, x in `metres` per unit.
fn contoured(lines: &Lines, metres: f64, v: &crate::geom::Vertex) -> f64 {
    if lines.times_x { v.x * metres * v.z } else { v.z }
}

/// Picture width on which one unit is a line width; wider pictures scale their lines and text.
const NOMINAL_WIDTH: f64 = 1024.0;

/// Between these mean triangle sides (in line widths) edges fade in: below the first a dense
/// mesh would look black, above the second they are fully drawn.
const FADE_FROM: f64 = 3.0;
const FADE_TO: f64 = 12.0;

/// Opacity of fully drawn edges: light enough that a triangle's colour stays readable.
const EDGE_OPACITY: f64 = 0.45;

/// Opacity of field lines: dark enough to follow across the brightest colours.
pub(crate) const FIELD_LINE_OPACITY: f64 = 0.85;

/// Opacity of the regions' white outlines.
pub(crate) const OUTLINE_OPACITY: f64 = 0.9;

/// Colours of the background and of text and frames.
pub(crate) const BACKGROUND: [u8; 3] = [255, 255, 255];
pub(crate) const INK: [u8; 3] = [34, 34, 34];

impl Layout {
    /// The layout of `result` on a picture `width` units wide with text of `text` size.
    pub fn new(result: &RunResult, width: f64, text: TextMetrics) -> Self {
        let mut bounds = result.bounds();
        // A refined mesh always spans a rectangle; this keeps an empty one drawable.
        if !(bounds[1] > bounds[0] && bounds[3] > bounds[2]) {
            bounds = [0.0, 1.0, 0.0, 1.0];
        }
        let (dx, dy) = (bounds[1] - bounds[0], bounds[3] - bounds[2]);
        let shading = Shading::of(result);
        let (lo, hi) = shading.range;
        let labels = [short(hi), short(lo)];
        let label_width = labels.iter().map(|l| text.width(l)).fold(0.0, f64::max);

        // Sizes are given for a 1024-unit picture and scale with it.
        let unit = width / NOMINAL_WIDTH;
        let margin = (24.0 * unit).round().max(2.0);
        let gap = (20.0 * unit).round().max(2.0);
        let bar_width = (24.0 * unit).round().max(3.0);
        let label_gap = (8.0 * unit).round().max(1.0);
        let beside = gap + bar_width + label_gap + label_width;
        // The y axis's labels go left of the plot, the x axis's under it.
        let tick_length = (6.0 * unit).round().max(2.0);
        let (x_ticks, y_ticks) = (ticks(bounds[0], bounds[1]), ticks(bounds[2], bounds[3]));
        let y_labels_width = y_ticks.iter().map(|(_, l)| text.width(l)).fold(0.0, f64::max);
        let before = y_labels_width + tick_length + label_gap;
        let box_width = (width - 2.0 * margin - beside - before).max(width / 4.0);
        // A tall domain fits a square box rather than making the picture taller than wide.
        let scale = (box_width / dx).min(box_width / dy);
        let (plot_width, plot_height) = (dx * scale, dy * scale);
        // Centred as a group, so a narrow plot does not leave the bar at the far left.
        let left = ((width - before - plot_width - beside) / 2.0).round().max(margin) + before;
        let plot = Frame { left, top: margin, width: plot_width, height: plot_height };
        let x_labels_bottom = plot.bottom() + tick_length + label_gap / 2.0 + text.char_height;
        // A flat plot still gets a bar tall enough for its two labels.
        let bar_height = plot_height.max(3.0 * text.line_height).round();
        let bar =
            Frame { left: (plot.right() + gap).round(), top: margin, width: bar_width, height: bar_height };
        let label_left = bar.right() + label_gap;
        let [max, min] = labels;
        let labels = [(max, label_left, bar.top), (min, label_left, bar.bottom() - text.char_height)];

        let per_line = ((width - 2.0 * margin) / text.char_width).floor().max(1.0) as usize;
        let mut segments = stats_segments(result);
        segments.extend(shading.legend());
        let lines = wrap(&segments, per_line);
        let text_top = (bar.bottom().max(x_labels_bottom) + 0.75 * margin).round();
        let height = (text_top + lines.len() as f64 * text.line_height + 0.75 * margin).ceil();
        let mut layout = Self {
            width,
            height,
            plot,
            bar,
            labels,
            ticks: Vec::new(),
            tick_labels: Vec::new(),
            lines,
            text_top,
            line_height: text.line_height,
            line_width: unit.max(1.0),
            bounds,
            shading,
            outlines: Vec::new(),
            region_names: Vec::new(),
            scale,
        };
        let (sides, boxes) = region_sides(result);
        let at = |v: u32| {
            let v = result.vertices[v as usize];
            layout.to_picture(v.x, v.y)
        };
        layout.outlines = sides.iter().map(|&[p, q]| [at(p), at(q)]).collect();
        let names = match &result.stats {
            Summary::Solution(s) => s.run.regions.iter().map(|r| r.name.clone()).collect(),
            Summary::Mesh(_) => Vec::new(),
        };
        let inset = 4.0 * unit;
        layout.region_names = (boxes.into_iter())
            .map(|(i, [x0, _, _, y1])| {
                let name = names.get(i).cloned().flatten().unwrap_or_else(|| format!("region {i}"));
                let (left, top) = layout.to_picture(x0, y1);
                (name, left + inset, top + inset)
            })
            .collect();
        // The ticks sit where their values are on the plot, outside its edges.
        for (x, label) in x_ticks {
            let at = layout.to_picture(x, bounds[3]).0;
            layout.ticks.push([at, plot.bottom(), at, plot.bottom() + tick_length]);
            let label_left = at - text.width(&label) / 2.0;
            layout.tick_labels.push((label, label_left, plot.bottom() + tick_length + label_gap / 2.0));
        }
        for (y, label) in y_ticks {
            let at = layout.to_picture(bounds[0], y).1;
            layout.ticks.push([plot.left, at, plot.left - tick_length, at]);
            let label_left = plot.left - tick_length - label_gap - text.width(&label);
            layout.tick_labels.push((label, label_left, at - text.char_height / 2.0));
        }
        layout
    }

    /// The picture point of the domain point (x, y), north up.
    pub fn to_picture(&self, x: f64, y: f64) -> (f64, f64) {
        let [x0, _, _, y1] = self.bounds;
        (self.plot.left + (x - x0) * self.scale, self.plot.top + (y1 - y) * self.scale)
    }

    /// Width of a field line: half again an edge's, so that lines stand out from a mesh.
    pub fn field_line_width(&self) -> f64 {
        1.5 * self.line_width
    }

    /// How opaque edges are drawn, given the mean triangle's size: 0 when they would crowd.
    pub fn edge_opacity(&self, triangles: usize) -> f64 {
        if triangles == 0 {
            return 0.0;
        }
        let area = self.plot.width * self.plot.height / triangles as f64;
        // The side of an equilateral triangle of the mean area, in line widths.
        let side = (area * 4.0 / 3f64.sqrt()).sqrt() / self.line_width;
        EDGE_OPACITY * ((side - FADE_FROM) / (FADE_TO - FADE_FROM)).clamp(0.0, 1.0)
    }
}

/// The sides of a result's regions, from its `region` field: the mesh edges between
/// triangles of different regions, and those on the domain's edge inside one (the mesh
/// follows every side, so these are the sides, less what a later region covers); and the box
/// [x0, x1, y0, y1] of each region's triangles, by region. Nothing without the field.
fn region_sides(result: &RunResult) -> (Vec<[u32; 2]>, BTreeMap<usize, [f64; 4]>) {
    let Some(field) = result.field("region").filter(|f| f.len() == result.triangles.len()) else {
        return Default::default();
    };
    let region = |t: usize| field.values[t];
    let mut triangle_of = HashMap::with_capacity(3 * result.triangles.len());
    for (t, &[a, b, c]) in result.triangles.iter().enumerate() {
        for edge in [(a, b), (b, c), (c, a)] {
            triangle_of.insert(edge, t);
        }
    }
    let (mut sides, mut boxes) = (Vec::new(), BTreeMap::new());
    for (t, &[a, b, c]) in result.triangles.iter().enumerate() {
        for (p, q) in [(a, b), (b, c), (c, a)] {
            // Each interior edge once, from its lower vertex id; a boundary edge has no twin.
            let side = match triangle_of.get(&(q, p)) {
                Some(&n) => p < q && region(n) != region(t),
                None => region(t) >= 0.0,
            };
            if side {
                sides.push([p, q]);
            }
        }
        if region(t) >= 0.0 {
            let bounds = boxes.entry(region(t) as usize).or_insert([
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ]);
            for v in [a, b, c] {
                let v = result.vertices[v as usize];
                *bounds = [bounds[0].min(v.x), bounds[1].max(v.x), bounds[2].min(v.y), bounds[3].max(v.y)];
            }
        }
    }
    (sides, boxes)
}

/// The area of `triangle` (counter-clockwise, as a result's triangles are).
fn area(result: &RunResult, triangle: [u32; 3]) -> f64 {
    let [a, b, c] = triangle.map(|v| result.vertices[v as usize].point());
    signed_area_x2(a, b, c) / 2.0
}

/// The smallest of `values` that at least `fraction` of the total weight lies at or under
/// (0 for no values).
fn weighted_quantile(values: &[f64], weights: &[f64], fraction: f64) -> f64 {
    let mut order: Vec<u32> = (0..values.len() as u32).collect();
    order.sort_unstable_by(|&s, &t| values[s as usize].total_cmp(&values[t as usize]).then(s.cmp(&t)));
    let total: f64 = order.iter().map(|&t| weights[t as usize]).sum();
    let mut under = 0.0;
    for &t in &order {
        under += weights[t as usize];
        if under >= fraction * total {
            return values[t as usize];
        }
    }
    order.last().map_or(0.0, |&t| values[t as usize])
}

/// The edges triangle `t` draws, so that each edge of the mesh is drawn once: an interior
/// edge by the triangle that has it from the lower vertex id to the higher (its neighbour has
/// it the other way), a boundary edge by its only triangle. `bounds` is `result.bounds()`.
pub(crate) fn owned_edges(
    result: &RunResult,
    bounds: [f64; 4],
    t: usize,
) -> impl Iterator<Item = (u32, u32)> + '_ {
    let [a, b, c] = result.triangles[t];
    [(a, b), (b, c), (c, a)].into_iter().filter(move |&(p, q)| p < q || on_one_side(result, bounds, p, q))
}

/// Whether p and q lie on the same side of the rectangle, so the edge pq is on the boundary.
/// Exact: a midpoint of two points on a side has that side's coordinate bit for bit.
fn on_one_side(result: &RunResult, [x0, x1, y0, y1]: [f64; 4], p: u32, q: u32) -> bool {
    let (p, q) = (result.vertices[p as usize], result.vertices[q as usize]);
    (p.x == q.x && (p.x == x0 || p.x == x1)) || (p.y == q.y && (p.y == y0 || p.y == y1))
}

/// The stats line in pieces that a wrapped line keeps whole.
pub(crate) fn stats_segments(result: &RunResult) -> Vec<String> {
    let mut segments = match &result.stats {
        Summary::Mesh(s) => {
            let mut segments = vec![
                format!("{} vertices", s.vertices),
                format!("{} triangles", s.triangles),
                format!("V_n {}", short(s.variation)),
            ];
            if let Some(e) = s.max_triangle_error {
                segments.push(format!("max e(T) {}", short(e)));
            }
            segments
        }
        Summary::Solution(s) => vec![
            format!("{} vertices", s.run.vertices),
            format!("{} solves", s.run.solves),
            format!("estimate {}", short(s.run.estimate)),
            format!("energy {}", short(s.run.energy)),
        ],
    };
    let stop = serde_json::to_value(result.stats.stop()).ok().and_then(|v| v.as_str().map(str::to_owned));
    segments.push(format!("stop {}", stop.unwrap_or_default()));
    segments
}

/// Joins `segments` with " · " into lines of at most `per_line` characters where it can (a
/// segment longer than a line gets a line of its own).
fn wrap(segments: &[String], per_line: usize) -> Vec<String> {
    const SEPARATOR: &str = " · ";
    let mut lines: Vec<String> = Vec::new();
    for segment in segments {
        match lines.last_mut() {
            Some(line) if line.chars().count() + 3 + segment.chars().count() <= per_line => {
                line.push_str(SEPARATOR);
                line.push_str(segment);
            }
            _ => lines.push(segment.clone()),
        }
    }
    lines
}

/// Round numbers from `lo` to `hi` for an axis, about five of them, 1, 2 or 5 × 10^k apart,
/// each with its label written to the step's precision (`0.2`, `500000`).
pub(crate) fn ticks(lo: f64, hi: f64) -> Vec<(f64, String)> {
    const ABOUT: f64 = 5.0;
    let raw = (hi - lo) / ABOUT;
    if !(raw > 0.0 && raw.is_finite()) {
        return Vec::new();
    }
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].map(|m| m * magnitude).into_iter().find(|&s| s >= raw).unwrap_or(raw);
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    // A hair of slack, so that an end on a multiple of the step (1e-3 / 2e-4) keeps its tick.
    let (first, last) = ((lo / step - 1e-9).ceil() as i64, (hi / step + 1e-9).floor() as i64);
    (first..=last)
        .map(|k| {
            let v = k as f64 * step;
            // `+ 0.0` writes a zero tick as 0, not -0.
            (v, format!("{:.decimals$}", v + 0.0))
        })
        .collect()
}

/// `v` with three significant digits, in plain notation from 0.001 to 99999, else as `2.47e-5`.
pub(crate) fn short(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{}", if v == 0.0 { 0.0 } else { v });
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
        let text = format!("{v:.decimals$}");
        match text.contains('.') {
            true => text.trim_end_matches('0').trim_end_matches('.').to_owned(),
            false => text,
        }
    } else {
        let text = format!("{v:.2e}");
        let (mantissa, exponent) = text.split_once('e').expect("LowerExp writes an exponent");
        format!("{}e{exponent}", mantissa.trim_end_matches('0').trim_end_matches('.'))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::Criterion;
    use crate::result::testing::{magnetic, sample, with_potential};

    const TEXT: TextMetrics = TextMetrics { char_width: 10.0, char_height: 20.0, line_height: 24.0 };

    #[test]
    fn a_regions_outline_is_its_sides_and_its_name_is_written_inside_it() {
        // The conductor [0.4, 0.6]² of `magnetic`, the mesh's only region.
        let result = magnetic(600);
        let region = result.field("region").expect("a solution with regions has the field");
        let inside = |x: f64, y: f64| (0.4..=0.6).contains(&x) && (0.4..=0.6).contains(&y);
        for (t, tri) in result.triangles.iter().enumerate() {
            let corners = tri.map(|v| result.vertices[v as usize]);
            let x = corners.iter().map(|v| v.x).sum::<f64>() / 3.0;
            let y = corners.iter().map(|v| v.y).sum::<f64>() / 3.0;
            assert_eq!(region.values[t], if inside(x, y) { 0.0 } else { -1.0 }, "triangle {t}");
        }
        let (sides, boxes) = region_sides(&result);
        let on_side =
            |p: crate::geom::Point| inside(p.x, p.y) && [p.x, p.y].iter().any(|&c| c == 0.4 || c == 0.6);
        let mut length = 0.0;
        for &[p, q] in &sides {
            let [p, q] = [p, q].map(|v| result.vertices[v as usize].point());
            assert!(on_side(p) && on_side(q) && (p.x == q.x || p.y == q.y), "{p:?} {q:?}");
            length += p.distance_sq(q).sqrt();
        }
        assert!((length - 0.8).abs() < 1e-12, "the sides add up to the perimeter: {length}");
        assert_eq!(boxes.into_iter().collect::<Vec<_>>(), [(0, [0.4, 0.6, 0.4, 0.6])]);
        let layout = Layout::new(&result, 1024.0, TEXT);
        assert_eq!(layout.outlines.len(), sides.len());
        let [(name, left, top)] = &layout.region_names[..] else { panic!("{:?}", layout.region_names) };
        let (x0, y1) = layout.to_picture(0.4, 0.6);
        assert_eq!(name, "region 0");
        assert!(*left > x0 && *top > y1 && *left < layout.to_picture(0.6, 0.4).0, "inside the square");
        // A mesh of F has no regions to draw.
        let mesh = Layout::new(&sample(300, Criterion::Error), 1024.0, TEXT);
        assert!(mesh.outlines.is_empty() && mesh.region_names.is_empty());
    }

    #[test]
    fn an_axisymmetric_fields_lines_follow_r_times_a() {
        // A_φ = 1/2 everywhere: flat, so planar lines would be none; r·A_φ = x/2 has straight
        // contours at constant x, which are the lines of B = (0, A/r) turned about the axis.
        let planar = with_potential(magnetic(300), |_, _| 0.5);
        let mut round = planar.clone();
        let at = round.fields.iter().position(|f| f.name == "B").unwrap();
        round.fields[at] = crate::solve::flux_density(
            crate::result::Geometry::Axisymmetric,
            &round.vertices,
            &round.triangles,
        );
        let pieces = |result: &RunResult| {
            let shading = Layout::new(result, 1024.0, TEXT).shading;
            let mut pieces = Vec::new();
            (0..result.triangles.len())
                .for_each(|t| shading.field_lines(result, t, |p, q| pieces.push([p, q])));
            pieces
        };
        assert!(pieces(&planar).is_empty());
        let lines = pieces(&round);
        assert!(lines.len() > 20, "{} pieces", lines.len());
        assert!(lines.iter().all(|[p, q]| (p[0] - q[0]).abs() < 1e-12), "every piece runs along z");
        let text = Layout::new(&round, 1024.0, TEXT).lines.join(" ");
        assert!(text.contains("Wb/rad of r·A"), "{text}");
        // The same device in mm: r·A, and the lines' spacing, stay in SI units.
        let mut in_mm = round.clone();
        in_mm.vertices.iter_mut().for_each(|v| (v.x, v.y) = (v.x * 1000.0, v.y * 1000.0));
        if let Summary::Solution(s) = &mut in_mm.stats {
            s.unit = Some(crate::result::Unit::Mm);
        }
        let spacing = |r: &RunResult| {
            let text = Layout::new(r, 1024.0, TEXT).lines.join(" ");
            text.split("field lines every ").nth(1).unwrap().split(' ').next().unwrap().to_owned()
        };
        assert_eq!(spacing(&in_mm), spacing(&round));
    }

    #[test]
    fn numbers_keep_three_significant_digits() {
        let cases = [
            (0.0625, "0.0625"),
            (2.4731e-5, "2.47e-5"),
            (1.0, "1"),
            (-0.25, "-0.25"),
            (123.456, "123"),
            (0.999_999, "1"),
            (2.5e7, "2.5e7"),
            (0.0, "0"),
            (-0.0, "0"),
        ];
        for (v, text) in cases {
            assert_eq!(short(v), text, "{v}");
        }
    }

    #[test]
    fn the_plot_keeps_the_domains_aspect_ratio_and_north_is_up() {
        let result = sample(50, Criterion::Variation);
        let layout = Layout::new(&result, 1024.0, TEXT);
        let [x0, x1, y0, y1] = result.bounds();
        let aspect = layout.plot.width / layout.plot.height;
        assert!((aspect - (x1 - x0) / (y1 - y0)).abs() < 1e-9, "{aspect}");
        assert_eq!(layout.to_picture(x0, y1), (layout.plot.left, layout.plot.top));
        let (right, bottom) = layout.to_picture(x1, y0);
        assert!((right - layout.plot.right()).abs() < 1e-9 && (bottom - layout.plot.bottom()).abs() < 1e-9);
        assert!(layout.bar.left > layout.plot.right() && layout.labels[0].1 + 40.0 < layout.width);
        assert!(layout.text_top > layout.plot.bottom() && layout.text_top + 24.0 < layout.height);
    }

    #[test]
    fn axes_tick_round_numbers_written_to_their_steps_precision() {
        let labels = |lo, hi| ticks(lo, hi).into_iter().map(|(_, l)| l).collect::<Vec<_>>();
        assert_eq!(labels(0.0, 1.0), ["0.0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
        assert_eq!(labels(0.0, 3.0), ["0", "1", "2", "3"]);
        assert_eq!(labels(-1.0, 1.0), ["-1.0", "-0.5", "0.0", "0.5", "1.0"]);
        assert_eq!(labels(500_015.0, 507_665.0), ["502000", "504000", "506000"]);
        assert_eq!(labels(0.0, 255.0), ["0", "100", "200"]);
        assert_eq!(labels(1e-3, 2e-3), ["0.0010", "0.0012", "0.0014", "0.0016", "0.0018", "0.0020"]);
        assert!(ticks(1.0, 1.0).is_empty());
    }

    #[test]
    fn tick_marks_sit_on_the_plots_edges_at_their_values_with_labels_outside() {
        let result = sample(50, Criterion::Variation);
        let layout = Layout::new(&result, 1024.0, TEXT);
        let [x0, x1, y0, y1] = result.bounds();
        let plot = layout.plot;
        let x_count = ticks(x0, x1).len();
        assert_eq!(layout.ticks.len(), x_count + ticks(y0, y1).len());
        for (i, &[ax, ay, bx, by]) in layout.ticks.iter().enumerate() {
            let (label, left, top) = &layout.tick_labels[i];
            let value: f64 = label.parse().unwrap();
            if i < x_count {
                assert!((ax - layout.to_picture(value, y0).0).abs() < 1e-9 && ax == bx);
                assert!(ay == plot.bottom() && by > ay && *top >= by, "{label}");
                assert!(*left > 0.0 && left + label.len() as f64 * TEXT.char_width < layout.width);
            } else {
                assert!((ay - layout.to_picture(x0, value).1).abs() < 1e-9 && ay == by);
                assert!(ax == plot.left && bx < ax, "{label}");
                assert!(*left >= 0.0 && left + label.len() as f64 * TEXT.char_width < bx, "{label}");
            }
        }
        let below = layout.tick_labels[..x_count].iter().map(|l| l.2 + TEXT.char_height).fold(0.0, f64::max);
        assert!(layout.text_top > below, "the stats line clears the x labels");
    }

    #[test]
    fn a_tall_domain_fits_a_square_box() {
        let mut result = sample(4, Criterion::Variation);
        result.vertices.iter_mut().for_each(|v| v.y *= 100.0);
        let layout = Layout::new(&result, 1024.0, TEXT);
        assert!(layout.plot.height <= 1024.0 && layout.height < 1200.0, "{layout:?}");
    }

    #[test]
    fn a_magnetostatic_solution_is_shaded_by_b_a_mesh_by_z_and_a_uniform_field_in_one_colour() {
        let mesh = sample(300, Criterion::Error);
        let range = mesh.z_range();
        assert_eq!(
            Shading::of(&mesh),
            Shading { coloured: None, range, max: range.1, levels: vec![], lines: None, metres: 1.0 }
        );
        let result = magnetic(500);
        let shading = Shading::of(&result);
        assert!(shading.range.0 < 0.1 * shading.range.1 && shading.levels.len() == FIELD_LINES);
        let text = Layout::new(&result, 1024.0, TEXT).lines.join(" ");
        assert!(text.contains("colour |B| in T") && text.contains("field lines every "), "{text}");
        // A = 3x − y: |B| = √10 on every triangle, to rounding.
        let result = with_potential(result, |x, y| 3.0 * x - y);
        let shading = Shading::of(&result);
        assert_eq!(shading.range.0, shading.range.1);
        assert!((shading.range.0 - 10f64.sqrt()).abs() < 1e-12, "{:?}", shading.range);
        let colours: std::collections::HashSet<[u8; 3]> =
            (0..result.triangles.len()).map(|t| shading.colour(&result, t)).collect();
        assert_eq!(colours.len(), 1);
    }

    #[test]
    fn the_b_scale_stops_under_99_percent_of_the_area_not_at_a_corners_peak() {
        assert_eq!(weighted_quantile(&[5.0, 1.0, 2.0, 3.0], &[1.0, 1.0, 1.0, 97.0], 0.99), 3.0);
        assert_eq!(weighted_quantile(&[5.0, 1.0, 2.0, 3.0], &[1.0, 1.0, 1.0, 96.0], 0.99), 5.0);
        assert_eq!(weighted_quantile(&[], &[], 0.99), 0.0);
        // One tiny triangle with a huge field does not set the scale; the legend says so.
        let result = with_potential(magnetic(500), |x, _| x);
        let t = (0..result.triangles.len())
            .min_by(|&s, &t| {
                area(&result, result.triangles[s]).total_cmp(&area(&result, result.triangles[t]))
            })
            .unwrap();
        let lift = result.triangles[t][0];
        let result = with_potential(result.clone(), |x, y| {
            let v = result.vertices[lift as usize];
            x + if (x, y) == (v.x, v.y) { 1.0 } else { 0.0 }
        });
        let shading = Shading::of(&result);
        assert!((shading.range.1 - 1.0).abs() < 1e-9, "{:?}", shading.range);
        assert!(shading.max > 10.0, "{}", shading.max);
        assert!(shading.legend().iter().any(|l| l.starts_with("max ") && l.ends_with(" above the bar")));
    }

    #[test]
    fn a_long_stats_line_wraps_between_segments() {
        let segments: Vec<String> =
            ["10000 vertices", "19681 triangles", "V_n 0.0625"].map(String::from).into();
        assert_eq!(wrap(&segments, 80), ["10000 vertices · 19681 triangles · V_n 0.0625"]);
        assert_eq!(wrap(&segments, 34), ["10000 vertices · 19681 triangles", "V_n 0.0625"]);
        assert_eq!(wrap(&segments, 5), ["10000 vertices", "19681 triangles", "V_n 0.0625"]);
    }

    #[test]
    fn edges_fade_out_as_triangles_shrink_to_a_few_pixels() {
        let result = sample(50, Criterion::Variation);
        let layout = Layout::new(&result, 1024.0, TEXT);
        assert_eq!(layout.edge_opacity(100), EDGE_OPACITY);
        assert_eq!(layout.edge_opacity(1_000_000), 0.0);
        let between = layout.edge_opacity(20_000);
        assert!(0.0 < between && between < EDGE_OPACITY, "{between}");
    }

    #[test]
    fn every_edge_of_the_mesh_is_owned_by_exactly_one_triangle() {
        let result = sample(300, Criterion::Error);
        let bounds = result.bounds();
        let mut owned: Vec<(u32, u32)> = (0..result.triangles.len())
            .flat_map(|t| owned_edges(&result, bounds, t))
            .map(|(p, q)| (p.min(q), p.max(q)))
            .collect();
        let mut all: Vec<(u32, u32)> = result
            .triangles
            .iter()
            .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
            .map(|(p, q)| (p.min(q), p.max(q)))
            .collect();
        owned.sort_unstable();
        all.sort_unstable();
        all.dedup();
        assert_eq!(owned, all);
    }
}

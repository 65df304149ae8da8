//! The mesh seen from above as SVG: one `<polygon>` per triangle filled with the colour of its
//! mean z (of its |B| for a magnetostatic solution), the edges as one `<path>`, a solution's
//! field lines as another, a colour bar and the stats line.
//!
//! The triangles, edges and field lines are rows, so a 10^6-triangle picture streams like the JSON
//! document. Coordinates are on a view box 1024 units wide, rounded to 0.01.

use super::picture::{self, BACKGROUND, INK, Layout, TextMetrics};
use super::{Encoded, Options, Part};
use crate::result::RunResult;
use std::fmt::Write as _;
use std::io::Write as _;
use std::sync::Arc;

/// Width of the view box: a line is one unit wide, as on a png of the default size.
const VIEW_WIDTH: f64 = 1024.0;

/// The font size; the advance is that of DejaVu Sans Mono and most monospace fonts (0.6 em).
const FONT_SIZE: f64 = 17.0;
const TEXT: TextMetrics =
    TextMetrics { char_width: 0.6 * FONT_SIZE, char_height: FONT_SIZE, line_height: 1.3 * FONT_SIZE };

/// How far below the top of a line of text its baseline is, in ems.
const ASCENT: f64 = 0.8;

/// Colour stops of the bar's gradient: viridis is smooth enough that 16 segments look like one.
const BAR_STOPS: usize = 16;

/// The picture of `result`; the options change nothing (its size is the view box's).
pub fn encode(result: &Arc<RunResult>, _options: &Options) -> Encoded {
    let layout = Arc::new(Layout::new(result, VIEW_WIDTH, TEXT));
    let range = layout.shading.range;
    let mut head = String::new();
    let (w, h) = (layout.width, layout.height);
    let _ = write!(
        head,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 {w} {h}\" width=\"{w}\" height=\"{h}\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"{}\"/>\n\
         <g id=\"mesh\" shape-rendering=\"crispEdges\">\n",
        hex(BACKGROUND)
    );
    // crispEdges: anti-aliased neighbours would let the background show through every shared
    // edge as a faint seam; the edges drawn on top are smooth anyway.
    let (r, l) = (result.clone(), layout.clone());
    let mut parts = vec![
        Part::Bytes(head.into_bytes()),
        Part::rows(result.triangles.len(), move |t, out| {
            let [a, b, c] = r.triangles[t].map(|v| {
                let v = r.vertices[v as usize];
                l.to_picture(v.x, v.y)
            });
            out.extend_from_slice(b"<polygon points=\"");
            for (i, p) in [a, b, c].into_iter().enumerate() {
                if i > 0 {
                    out.push(b' ');
                }
                point(out, p, b',');
            }
            out.extend_from_slice(b"\" fill=\"");
            out.extend_from_slice(hex(l.shading.colour(&r, t)).as_bytes());
            out.extend_from_slice(b"\"/>\n");
        }),
        Part::Bytes(b"</g>\n".to_vec()),
    ];
    // Rounded as written, so a mesh whose edges fade to nothing writes none.
    let opacity = (layout.edge_opacity(result.triangles.len()) * 100.0).round() / 100.0;
    if opacity > 0.0 {
        let head = format!(
            "<path id=\"edges\" fill=\"none\" stroke=\"{}\" stroke-opacity=\"{opacity:.2}\" \
             stroke-width=\"{}\" stroke-linecap=\"round\" d=\"",
            hex(INK),
            layout.line_width
        );
        let (r, l, bounds) = (result.clone(), layout.clone(), layout.bounds);
        parts.extend([
            Part::Bytes(head.into_bytes()),
            Part::rows(result.triangles.len(), move |t, out| {
                for (p, q) in picture::owned_edges(&r, bounds, t) {
                    let [p, q] = [p, q].map(|v| {
                        let v = r.vertices[v as usize];
                        l.to_picture(v.x, v.y)
                    });
                    out.push(b'M');
                    point(out, p, b' ');
                    out.push(b'L');
                    point(out, q, b' ');
                }
            }),
            Part::Bytes(b"\"/>\n".to_vec()),
        ]);
    }
    if !layout.shading.levels.is_empty() {
        let head = format!(
            "<path id=\"field-lines\" fill=\"none\" stroke=\"{}\" stroke-opacity=\"{}\" stroke-width=\"{}\" \
             stroke-linecap=\"round\" d=\"",
            hex(INK),
            picture::FIELD_LINE_OPACITY,
            layout.field_line_width()
        );
        let (r, l) = (result.clone(), layout.clone());
        parts.extend([
            Part::Bytes(head.into_bytes()),
            Part::rows(result.triangles.len(), move |t, out| {
                l.shading.field_lines(&r, t, |p, q| {
                    out.push(b'M');
                    point(out, l.to_picture(p[0], p[1]), b' ');
                    out.push(b'L');
                    point(out, l.to_picture(q[0], q[1]), b' ');
                });
            }),
            Part::Bytes(b"\"/>\n".to_vec()),
        ]);
    }
    parts.push(Part::Bytes(regions(&layout).into_bytes()));
    parts.push(Part::Bytes(trailer(&layout, range).into_bytes()));
    Encoded::new(parts)
}

/// The regions' outlines in white over the field, and their names, white on a dark halo
/// that reads over any colour.
fn regions(layout: &Layout) -> String {
    let mut s = String::new();
    if layout.outlines.is_empty() {
        return s;
    }
    let _ = write!(
        s,
        "<path id=\"outlines\" fill=\"none\" stroke=\"#ffffff\" stroke-opacity=\"{}\" stroke-width=\"{}\" \
         stroke-linecap=\"round\" d=\"",
        picture::OUTLINE_OPACITY,
        layout.field_line_width()
    );
    for &[p, q] in &layout.outlines {
        let _ = write!(s, "M{} {}L{} {}", round(p.0), round(p.1), round(q.0), round(q.1));
    }
    s.push_str("\"/>\n");
    let _ = writeln!(
        s,
        "<g id=\"region-names\" fill=\"#ffffff\" stroke=\"{}\" stroke-width=\"{}\" paint-order=\"stroke\" \
         font-family=\"DejaVu Sans Mono, Menlo, Consolas, monospace\" font-size=\"{FONT_SIZE}\">",
        hex(INK),
        3.0 * layout.line_width
    );
    for (name, left, top) in &layout.region_names {
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\">{}</text>",
            round(*left),
            round(top + ASCENT * FONT_SIZE),
            escape(name)
        );
    }
    s.push_str("</g>\n");
    s
}

/// The axes' ticks, the colour bar, their labels and the stats line.
fn trailer(layout: &Layout, (lo, hi): (f64, f64)) -> String {
    let mut s = String::from("<defs><linearGradient id=\"scale\" x1=\"0\" y1=\"1\" x2=\"0\" y2=\"0\">");
    for i in 0..=BAR_STOPS {
        let t = i as f64 / BAR_STOPS as f64;
        let colour = hex(super::colour::of(lo + t * (hi - lo), lo, hi));
        let _ = write!(s, "<stop offset=\"{t}\" stop-color=\"{colour}\"/>");
    }
    s.push_str("</linearGradient></defs>\n");
    let _ =
        write!(s, "<path id=\"ticks\" stroke=\"{}\" stroke-width=\"{}\" d=\"", hex(INK), layout.line_width);
    for &[x1, y1, x2, y2] in &layout.ticks {
        let _ = write!(s, "M{} {}L{} {}", round(x1), round(y1), round(x2), round(y2));
    }
    s.push_str("\"/>\n");
    let bar = layout.bar;
    let _ = write!(
        s,
        "\
         <rect id=\"bar\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"url(#scale)\" stroke=\"{}\" \
         stroke-width=\"{}\"/>\n\
         <g fill=\"{}\" font-family=\"DejaVu Sans Mono, Menlo, Consolas, monospace\" font-size=\"{FONT_SIZE}\">\n",
        bar.left,
        bar.top,
        bar.width,
        bar.height,
        hex(INK),
        layout.line_width,
        hex(INK)
    );
    for (text, left, top) in layout.labels.iter().chain(&layout.tick_labels) {
        let _ = writeln!(
            s,
            "<text x=\"{left}\" y=\"{}\">{}</text>",
            round(top + ASCENT * FONT_SIZE),
            escape(text)
        );
    }
    for (i, line) in layout.lines.iter().enumerate() {
        let baseline = layout.text_top + i as f64 * layout.line_height + ASCENT * FONT_SIZE;
        let _ = writeln!(
            s,
            "<text class=\"stats\" x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            layout.width / 2.0,
            round(baseline),
            escape(line)
        );
    }
    s.push_str("</g>\n</svg>\n");
    s
}

/// Appends `x{separator}y`, each rounded to 0.01 without trailing zeros.
fn point(out: &mut Vec<u8>, (x, y): (f64, f64), separator: u8) {
    number(out, x);
    out.push(separator);
    number(out, y);
}

/// Appends `v` rounded to 0.01: `12`, `12.5`, `12.25`.
fn number(out: &mut Vec<u8>, v: f64) {
    let hundredths = (v * 100.0).round() as i64;
    if hundredths < 0 {
        out.push(b'-');
    }
    let n = hundredths.unsigned_abs();
    // Writing into a Vec does not fail, and `write!` to it allocates nothing per number.
    let _ = match n % 100 {
        0 => write!(out, "{}", n / 100),
        f if f % 10 == 0 => write!(out, "{}.{}", n / 100, f / 10),
        f => write!(out, "{}.{f:02}", n / 100),
    };
}

/// `v` rounded to 0.01, as text.
fn round(v: f64) -> String {
    let mut out = Vec::new();
    number(&mut out, v);
    String::from_utf8(out).expect("digits are ASCII")
}

/// `#rrggbb`.
fn hex([r, g, b]: [u8; 3]) -> String {
    format!("#{r:02x}{g:02x}{b:02x}")
}

/// `text` with the characters XML reserves in text escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::colour;
    use crate::refine::Criterion;
    use crate::result::testing::{magnetic, sample};

    fn svg(result: &Arc<RunResult>) -> String {
        String::from_utf8(encode(result, &Options::default()).to_vec()).unwrap()
    }

    fn parse_hex(text: &str) -> [u8; 3] {
        let v = u32::from_str_radix(text.strip_prefix('#').unwrap(), 16).unwrap();
        [(v >> 16) as u8, (v >> 8) as u8, v as u8]
    }

    #[test]
    fn each_triangle_is_one_polygon_filled_with_the_colour_of_its_mean_z() {
        let result = Arc::new(sample(200, Criterion::Error));
        let text = svg(&result);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let polygons: Vec<_> = doc.descendants().filter(|n| n.has_tag_name("polygon")).collect();
        assert_eq!(polygons.len(), result.triangles.len());
        let (lo, hi) = result.z_range();
        for t in [0, 1, 57, result.triangles.len() - 1] {
            let z = result.triangles[t].iter().map(|&v| result.vertices[v as usize].z).sum::<f64>() / 3.0;
            assert_eq!(
                parse_hex(polygons[t].attribute("fill").unwrap()),
                colour::of(z, lo, hi),
                "triangle {t}"
            );
        }
    }

    #[test]
    fn the_plot_has_the_domains_aspect_ratio_and_north_is_up() {
        let result = Arc::new(sample(200, Criterion::Variation));
        let text = svg(&result);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let view: Vec<f64> =
            doc.root_element().attribute("viewBox").unwrap().split(' ').map(|v| v.parse().unwrap()).collect();
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        for polygon in doc.descendants().filter(|n| n.has_tag_name("polygon")) {
            for p in polygon.attribute("points").unwrap().split(' ') {
                let (x, y) = p.split_once(',').unwrap();
                xs.push(x.parse::<f64>().unwrap());
                ys.push(y.parse::<f64>().unwrap());
            }
        }
        let extent = |v: &[f64]| {
            v.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x))
                - v.iter().fold(f64::INFINITY, |m, &x| m.min(x))
        };
        let [x0, x1, y0, y1] = result.bounds();
        let aspect = extent(&xs) / extent(&ys);
        assert!((aspect - (x1 - x0) / (y1 - y0)).abs() < 1e-3, "{aspect}");
        assert!(xs.iter().chain(&ys).all(|&c| c >= 0.0) && xs.iter().all(|&x| x <= view[2]));
        // The vertex with the largest y is drawn highest (the smallest picture y).
        let top = (0..result.vertices.len())
            .max_by(|&a, &b| result.vertices[a].y.total_cmp(&result.vertices[b].y))
            .unwrap();
        let t = result.triangles.iter().position(|tri| tri.contains(&(top as u32))).unwrap();
        let k = result.triangles[t].iter().position(|&v| v == top as u32).unwrap();
        let polygon = doc.descendants().filter(|n| n.has_tag_name("polygon")).nth(t).unwrap();
        let y_top: f64 = polygon
            .attribute("points")
            .unwrap()
            .split(' ')
            .nth(k)
            .unwrap()
            .split_once(',')
            .unwrap()
            .1
            .parse()
            .unwrap();
        assert_eq!(y_top, ys.iter().fold(f64::INFINITY, |m, &y| m.min(y)));
    }

    #[test]
    fn the_text_names_the_vertex_count_and_the_bar_its_range() {
        let result = Arc::new(sample(300, Criterion::Error));
        let text = svg(&result);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let texts: Vec<&str> =
            doc.descendants().filter(|n| n.has_tag_name("text")).filter_map(|n| n.text()).collect();
        let all = texts.join(" ");
        assert!(all.contains("300 vertices"), "{all}");
        assert!(all.contains(&format!("{} triangles", result.triangles.len())), "{all}");
        let (lo, hi) = result.z_range();
        assert_eq!(texts[..2], [picture::short(hi), picture::short(lo)]);
        assert!(doc.descendants().any(|n| n.attribute("id") == Some("bar")));
    }

    #[test]
    fn the_edges_path_draws_each_edge_once() {
        let result = Arc::new(sample(100, Criterion::Error));
        let text = svg(&result);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let edges = doc.descendants().find(|n| n.attribute("id") == Some("edges")).unwrap();
        let segments = edges.attribute("d").unwrap().matches('M').count();
        // Euler: E = V + T - 1 for a triangulated disk.
        assert_eq!(segments, result.vertices.len() + result.triangles.len() - 1);
    }

    #[test]
    fn a_magnetostatic_solution_is_coloured_by_b_with_its_field_lines_over_it() {
        let result = Arc::new(magnetic(600));
        let text = svg(&result);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let field = result.field("B").unwrap();
        let b: Vec<f64> = (0..field.len()).map(|t| field.magnitude(t)).collect();
        let layout = Layout::new(&result, VIEW_WIDTH, TEXT);
        // The scale runs from the least |B| to below the greatest (picture's tests say where).
        let (lo, hi) = layout.shading.range;
        assert!(
            lo == b.iter().copied().fold(f64::INFINITY, f64::min)
                && hi < b.iter().copied().fold(0.0, f64::max)
        );
        let polygons: Vec<_> = doc.descendants().filter(|n| n.has_tag_name("polygon")).collect();
        for t in 0..result.triangles.len() {
            assert_eq!(parse_hex(polygons[t].attribute("fill").unwrap()), colour::of(b[t], lo, hi), "{t}");
        }
        // One piece per triangle and level that the level crosses.
        let lines = doc.descendants().find(|n| n.attribute("id") == Some("field-lines")).unwrap();
        let mut pieces = 0;
        (0..result.triangles.len()).for_each(|t| layout.shading.field_lines(&result, t, |_, _| pieces += 1));
        assert!(pieces > 100, "{pieces}");
        assert_eq!(lines.attribute("d").unwrap().matches('M').count(), pieces);
        let texts: Vec<&str> = (doc.descendants())
            .filter(|n| n.has_tag_name("text"))
            .filter(|n| n.parent().and_then(|g| g.attribute("id")) != Some("region-names"))
            .filter_map(|n| n.text())
            .collect();
        assert_eq!(texts[..2], [picture::short(hi), picture::short(lo)]);
        let all = texts.join(" ");
        assert!(all.contains("colour |B| in T") && all.contains("field lines every"), "{all}");
        // A mesh has neither.
        let mesh = svg(&Arc::new(sample(600, Criterion::Error)));
        assert!(!mesh.contains("field-lines") && !mesh.contains("|B|"));
    }

    #[test]
    fn a_solutions_regions_are_outlined_and_named() {
        let result = Arc::new(magnetic(600));
        let text = svg(&result);
        let doc = roxmltree::Document::parse(&text).unwrap();
        let layout = Layout::new(&result, VIEW_WIDTH, TEXT);
        let outlines = doc.descendants().find(|n| n.attribute("id") == Some("outlines")).unwrap();
        assert_eq!(outlines.attribute("d").unwrap().matches('M').count(), layout.outlines.len());
        let names = doc.descendants().find(|n| n.attribute("id") == Some("region-names")).unwrap();
        let written: Vec<&str> =
            names.children().filter_map(|n| n.text()).filter(|t| !t.trim().is_empty()).collect();
        assert_eq!(written, ["region 0"]);
        let mesh = svg(&Arc::new(sample(600, Criterion::Error)));
        assert!(!mesh.contains("outlines") && !mesh.contains("region-names"));
    }

    #[test]
    fn coordinates_are_rounded_to_hundredths() {
        let mut out = Vec::new();
        for v in [12.0, 12.5, 12.254, 0.004, 3.999, -1.25] {
            number(&mut out, v);
            out.push(b' ');
        }
        assert_eq!(String::from_utf8(out).unwrap(), "12 12.5 12.25 0 4 -1.25 ");
    }

    #[test]
    fn the_chunks_are_the_same_bytes_as_the_whole() {
        let result = Arc::new(sample(20_000, Criterion::Error));
        let options = Options::default();
        let chunks: Vec<Vec<u8>> = encode(&result, &options).into_chunks().collect();
        assert!(chunks.len() > 1);
        assert_eq!(chunks.concat(), encode(&result, &options).to_vec());
    }
}

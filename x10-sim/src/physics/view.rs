//! The arena seen from above: walls, boxes, floor lines, the lamp, the chassis's path, the
//! ranger's beam at each reading and the contacts; on the run's page, a slider moves the robot
//! along its path and the time cursor across the device lanes.

use std::fmt::Write as _;

use super::engine::Motion;
use crate::exec::Nanos;

/// Width of the top view, px (its height follows the arena's proportions).
pub const TOP_VIEW_WIDTH: f64 = 480.0;

/// The path's points are this far apart in time, ns.
pub const TOP_VIEW_SAMPLE_NS: Nanos = 20_000_000;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The bounds of everything drawn (mm): arena, lines, lamp, path, with a margin.
fn bounds(m: &Motion) -> (f64, f64, f64, f64) {
    let a = &m.physics().arena;
    let mut pts: Vec<(f64, f64)> = Vec::new();
    pts.extend(a.walls.iter().flat_map(|w| [w.from, w.to]));
    pts.extend(a.boxes.iter().flat_map(|b| [b.min, b.max]));
    pts.extend(a.lines.iter().flat_map(|l| l.points.iter().copied()));
    pts.extend(a.lamp.map(|l| l.at));
    let r = m.physics().chassis.as_ref().map_or(0.0, |c| c.radius_mm);
    for s in m.samples(TOP_VIEW_SAMPLE_NS) {
        pts.push((s.pose.x_mm - r, s.pose.y_mm - r));
        pts.push((s.pose.x_mm + r, s.pose.y_mm + r));
    }
    let fin = |v: f64| if v.is_finite() { v } else { 0.0 };
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for (x, y) in pts {
        x0 = x0.min(fin(x));
        y0 = y0.min(fin(y));
        x1 = x1.max(fin(x));
        y1 = y1.max(fin(y));
    }
    if x0 > x1 {
        return (-500.0, -500.0, 500.0, 500.0);
    }
    let margin = 40.0;
    (
        x0 - margin,
        y0 - margin,
        (x1 + margin).max(x0 + 100.0),
        (y1 + margin).max(y0 + 100.0),
    )
}

/// The top view of a run's models as an SVG picture (`id="x10-arena"`): the arena, the path
/// (green), the ranger's beam at each reading (orange, to its hit), each contact (red, with
/// what it touched and when), the chassis at the end (`id="x10-robot"`). The path's points
/// are in `data-path` (`t_s,x,y,heading;…`) for the page's slider.
pub fn top_view_svg(m: &Motion) -> String {
    let (x0, y0, x1, y1) = bounds(m);
    let scale = TOP_VIEW_WIDTH / (x1 - x0);
    let height = ((y1 - y0) * scale).round().clamp(60.0, 2_000.0);
    let px = |p: (f64, f64)| ((p.0 - x0) * scale, height - (p.1 - y0) * scale);
    let samples = m.samples(TOP_VIEW_SAMPLE_NS);
    let mut data = String::new();
    for s in &samples {
        let (x, y) = px((s.pose.x_mm, s.pose.y_mm));
        let _ = write!(
            data,
            "{:.3},{x:.1},{y:.1},{:.1};",
            s.t_ns as f64 / 1e9,
            s.pose.heading_deg
        );
    }
    let mut o = String::new();
    let _ = writeln!(
        o,
        r#"<svg xmlns="http://www.w3.org/2000/svg" id="x10-arena" width="{TOP_VIEW_WIDTH:.0}" height="{height:.0}" viewBox="0 0 {TOP_VIEW_WIDTH:.0} {height:.0}" font-family="DejaVu Sans, Verdana, sans-serif" font-size="11" data-end-s="{:.3}" data-scale="{scale:.5}" data-path="{data}">"#,
        m.end_ns() as f64 / 1e9
    );
    let _ = writeln!(
        o,
        r##"<rect x="0" y="0" width="{TOP_VIEW_WIDTH:.0}" height="{height:.0}" fill="#f6f8fa"/>"##
    );
    let a = &m.physics().arena;
    for l in &a.lines {
        let pts: Vec<String> = l
            .points
            .iter()
            .map(|p| {
                let (x, y) = px(*p);
                format!("{x:.1},{y:.1}")
            })
            .collect();
        let grey = (l.reflectance.clamp(0.0, 1.0) * 220.0).round() as u8;
        let _ = writeln!(
            o,
            r#"<polyline class="floor-line" points="{}" fill="none" stroke="rgb({grey},{grey},{grey})" stroke-width="{:.1}" stroke-linejoin="round"><title>floor line {} mm wide, reflectance {}</title></polyline>"#,
            pts.join(" "),
            (l.width_mm * scale).max(1.0),
            l.width_mm,
            l.reflectance
        );
    }
    for (i, w) in a.walls.iter().enumerate() {
        let (ax, ay) = px(w.from);
        let (bx, by) = px(w.to);
        let _ = writeln!(
            o,
            r##"<line class="wall" x1="{ax:.1}" y1="{ay:.1}" x2="{bx:.1}" y2="{by:.1}" stroke="#24292f" stroke-width="3"><title>wall {}</title></line>"##,
            i + 1
        );
    }
    for (i, b) in a.boxes.iter().enumerate() {
        let (ax, ay) = px((b.min.0, b.max.1));
        let _ = writeln!(
            o,
            r##"<rect class="box" x="{ax:.1}" y="{ay:.1}" width="{:.1}" height="{:.1}" fill="#8c959f" stroke="#24292f"><title>box {}</title></rect>"##,
            (b.max.0 - b.min.0) * scale,
            (b.max.1 - b.min.1) * scale,
            i + 1
        );
    }
    if let Some(l) = a.lamp {
        let (x, y) = px(l.at);
        let _ = writeln!(
            o,
            r##"<circle class="lamp" cx="{x:.1}" cy="{y:.1}" r="6" fill="#f2cc60" stroke="#9a6700"><title>lamp</title></circle>"##
        );
    }
    for r in m.ranger_readings() {
        let (ax, ay) = px(r.from);
        let (len, words) = match r.distance_mm {
            Some(d) => (d, format!("{d:.0} mm")),
            None => (400.0, "nothing in range".to_string()),
        };
        let a = r.angle_deg.to_radians();
        let (bx, by) = px((r.from.0 + len * a.cos(), r.from.1 + len * a.sin()));
        let _ = writeln!(
            o,
            r##"<line class="beam" data-t="{:.3}" x1="{ax:.1}" y1="{ay:.1}" x2="{bx:.1}" y2="{by:.1}" stroke="#fb8f44" stroke-opacity="0.35" stroke-width="1"><title>{} {:.3} s: {}</title></line>"##,
            r.t_ns as f64 / 1e9,
            esc(&r.device),
            r.t_ns as f64 / 1e9,
            words
        );
    }
    let path: Vec<String> = samples
        .iter()
        .map(|s| {
            let (x, y) = px((s.pose.x_mm, s.pose.y_mm));
            format!("{x:.1},{y:.1}")
        })
        .collect();
    let _ = writeln!(
        o,
        r##"<polyline class="path" points="{}" fill="none" stroke="#1a7f37" stroke-width="1.5"/>"##,
        path.join(" ")
    );
    for c in m.contacts() {
        let (x, y) = px(c.at);
        let _ = writeln!(
            o,
            r##"<circle class="contact" cx="{x:.1}" cy="{y:.1}" r="4" fill="#cf222e"><title>{:.3} s: touched {}</title></circle>"##,
            c.t_ns as f64 / 1e9,
            esc(&c.obstacle)
        );
    }
    if let Some(ch) = &m.physics().chassis {
        let p = m.end_pose();
        let (x, y) = px((p.x_mm, p.y_mm));
        let r = ch.radius_mm * scale;
        let _ = writeln!(
            o,
            r##"<g id="x10-robot" transform="translate({x:.1},{y:.1}) rotate({:.1})"><circle r="{r:.1}" fill="#0969da" fill-opacity="0.25" stroke="#0969da"/><line x1="0" y1="0" x2="{r:.1}" y2="0" stroke="#0969da" stroke-width="2"/></g>"##,
            -p.heading_deg
        );
    }
    let _ = writeln!(
        o,
        r##"<text x="6" y="{:.1}" fill="#57606a">{:.0} mm across</text>"##,
        height - 6.0,
        x1 - x0
    );
    o.push_str("</svg>\n");
    o
}

/// The page's section for the top view: the picture, a slider over the run's time that moves
/// the robot along its path and a cursor across the timeline, and the script that does it.
pub(crate) fn top_view_section(m: &Motion) -> String {
    format!(
        r#"<h2>Arena</h2>
<div class="tools"><input id="x10-scrub" type="range" min="0" max="{max}" step="1" value="{max}" style="width:480px"> <span id="x10-scrub-t">{end:.3} s</span> · move the slider: the robot along its path, the cursor across the lanes</div>
{svg}<script>
{SCRUB}</script>
"#,
        max = m.samples(TOP_VIEW_SAMPLE_NS).len().saturating_sub(1),
        end = m.end_ns() as f64 / 1e9,
        svg = top_view_svg(m)
    )
}

/// Slider → robot marker and time cursor.
const SCRUB: &str = include_str!("scrub.js");

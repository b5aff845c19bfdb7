//! Plane geometry for the arena: distances to segments, ray casts. Millimetres, `f64`.

/// A point or vector.
pub(crate) type P = (f64, f64);

/// A segment of an obstacle: a wall, or one side of a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Seg {
    pub a: P,
    pub b: P,
    /// Index of its obstacle: walls first, then boxes.
    pub obstacle: usize,
}

/// The point of segment `a`–`b` nearest to `p`.
pub(crate) fn nearest_on(p: P, a: P, b: P) -> P {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    if len2 == 0.0 {
        return a;
    }
    let t = (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0);
    (a.0 + t * dx, a.1 + t * dy)
}

/// Distance from `p` to `q`.
pub(crate) fn dist(p: P, q: P) -> f64 {
    let (dx, dy) = (p.0 - q.0, p.1 - q.1);
    (dx * dx + dy * dy).sqrt()
}

/// Distance from `p` to segment `a`–`b`.
pub(crate) fn dist_to_segment(p: P, a: P, b: P) -> f64 {
    dist(p, nearest_on(p, a, b))
}

/// Distance from `p` to a polyline (infinite for fewer than one point).
pub(crate) fn dist_to_polyline(p: P, points: &[P]) -> f64 {
    match points {
        [] => f64::INFINITY,
        [one] => dist(p, *one),
        _ => points
            .windows(2)
            .map(|w| dist_to_segment(p, w[0], w[1]))
            .fold(f64::INFINITY, f64::min),
    }
}

/// How far along the ray from `o` in unit direction `d` it meets segment `a`–`b`, if it does
/// (at a distance ≥ 0).
pub(crate) fn ray_hit(o: P, d: P, a: P, b: P) -> Option<f64> {
    let e = (b.0 - a.0, b.1 - a.1);
    let denom = d.0 * e.1 - d.1 * e.0;
    if denom.abs() < 1e-12 {
        return None;
    }
    let w = (a.0 - o.0, a.1 - o.1);
    let t = (w.0 * e.1 - w.1 * e.0) / denom;
    let u = (w.0 * d.1 - w.1 * d.0) / denom;
    (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
}

/// The segments of walls and boxes, walls first.
pub(crate) fn segments(walls: &[(P, P)], boxes: &[(P, P)]) -> Vec<Seg> {
    let mut v: Vec<Seg> = walls
        .iter()
        .enumerate()
        .map(|(i, (a, b))| Seg {
            a: *a,
            b: *b,
            obstacle: i,
        })
        .collect();
    for (j, (min, max)) in boxes.iter().enumerate() {
        let obstacle = walls.len() + j;
        let c = [
            (min.0, min.1),
            (max.0, min.1),
            (max.0, max.1),
            (min.0, max.1),
        ];
        for i in 0..4 {
            v.push(Seg {
                a: c[i],
                b: c[(i + 1) % 4],
                obstacle,
            });
        }
    }
    v
}

/// The nearest obstacle segment to `p`: its distance, its nearest point and its obstacle
/// (compared by squared distance; one square root for the nearest).
pub(crate) fn nearest(p: P, segs: &[Seg]) -> Option<(f64, P, usize)> {
    segs.iter()
        .map(|s| {
            let q = nearest_on(p, s.a, s.b);
            let (dx, dy) = (p.0 - q.0, p.1 - q.1);
            (dx * dx + dy * dy, q, s.obstacle)
        })
        .min_by(|x, y| x.0.total_cmp(&y.0))
        .map(|(d2, q, o)| (d2.sqrt(), q, o))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_and_rays() {
        assert_eq!(dist_to_segment((0.0, 5.0), (-1.0, 0.0), (1.0, 0.0)), 5.0);
        assert_eq!(dist_to_segment((4.0, 3.0), (-1.0, 0.0), (0.0, 0.0)), 5.0);
        assert_eq!(
            ray_hit((0.0, 0.0), (1.0, 0.0), (10.0, -1.0), (10.0, 1.0)),
            Some(10.0)
        );
        assert_eq!(
            ray_hit((0.0, 0.0), (-1.0, 0.0), (10.0, -1.0), (10.0, 1.0)),
            None
        );
        assert_eq!(
            ray_hit((0.0, 0.0), (0.0, 1.0), (10.0, -1.0), (10.0, 1.0)),
            None
        );
        assert_eq!(
            dist_to_polyline((5.0, 2.0), &[(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)]),
            2.0
        );
        let segs = segments(
            &[((0.0, 0.0), (100.0, 0.0))],
            &[((50.0, 50.0), (60.0, 60.0))],
        );
        assert_eq!(segs.len(), 5);
        assert_eq!(nearest((55.0, 40.0), &segs), Some((10.0, (55.0, 50.0), 1)));
    }
}

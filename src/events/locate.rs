//! Where a source is, from the arrival times of its event's hits.
//!
//! * Linear (a strip between two sensors): the first two located hits, a nearer and a
//!   farther sensor a distance L apart, give x = (L − v·Δt)/2 from the nearer one along the
//!   line. |v·Δt| > L means the source lies beyond the nearer sensor: x is clamped to it and
//!   flagged `beyond_sensor`.
//! * Planar (three or more sensors): the point whose distance differences to the first-hit
//!   sensor best match v·Δt in least squares, i.e. the minimum of LUCY, found by
//!   Gauss–Newton (Geiger's method) with Levenberg–Marquardt damping from the sensors'
//!   centroid; when that does not converge, a grid search over the sensors' bounding box
//!   (twice its size) and the damped iteration again from the best grid point.
//! * LUCY (Vallen's location uncertainty, as vallenae's `ex5_location.py` defines it): the
//!   RMS of the distance-difference residuals, ‖(|p−s_k| − |p−s_1|) − v·(t_k − t_1)‖ / √(n−1)
//!   over the n located hits in arrival order, metres.

use super::settings::ZoneSpec;
use crate::model::LocationKind;

/// One located hit: its sensor and arrival time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arrival {
    pub x: f64,
    pub y: f64,
    pub t: f64,
}

/// What location gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    Located,
    /// Linear: clamped to the nearer sensor (the source lies beyond it).
    BeyondSensor,
    /// Planar: the damped Gauss–Newton did not converge from the centroid; the grid
    /// fallback gave the point.
    Fallback,
    /// Fewer located hits than the method needs (1 for linear, 2 for planar).
    TooFewHits,
}

impl Status {
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Located => "located",
            Status::BeyondSensor => "beyond_sensor",
            Status::Fallback => "fallback",
            Status::TooFewHits => "too_few_hits",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Location {
    pub x: f64,
    /// None for linear location.
    pub y: Option<f64>,
    pub lucy: f64,
    pub iterations: u32,
    pub status: Status,
}

/// LUCY at (x, y) for arrivals in arrival order.
pub fn lucy(a: &[Arrival], v: f64, x: f64, y: f64) -> f64 {
    if a.len() < 2 {
        return 0.0;
    }
    let d0 = (x - a[0].x).hypot(y - a[0].y);
    let ss: f64 = a[1..]
        .iter()
        .map(|k| {
            let r = ((x - k.x).hypot(y - k.y) - d0) - v * (k.t - a[0].t);
            r * r
        })
        .sum();
    ss.sqrt() / ((a.len() - 1) as f64).sqrt()
}

/// Linear location from arrivals (sensor positions along the line in `x`), sorted by arrival.
pub fn linear(a: &[Arrival], v: f64) -> Option<Location> {
    let first = *a.first()?;
    // The next hit at another position (two sensors at one place say nothing).
    let Some(second) = a[1..].iter().find(|k| k.x != first.x).copied() else {
        return Some(Location {
            x: first.x,
            y: None,
            lucy: 0.0,
            iterations: 0,
            status: Status::TooFewHits,
        });
    };
    let l = (second.x - first.x).abs();
    let dir = (second.x - first.x).signum();
    let s = (l - v * (second.t - first.t)) / 2.0;
    let (s, status) = if s < 0.0 {
        (0.0, Status::BeyondSensor)
    } else if s > l {
        (l, Status::BeyondSensor)
    } else {
        (s, Status::Located)
    };
    let x = first.x + dir * s;
    let used: Vec<Arrival> = a.iter().map(|k| Arrival { y: 0.0, ..*k }).collect();
    Some(Location {
        x,
        y: None,
        lucy: lucy(&used, v, x, 0.0),
        iterations: 0,
        status,
    })
}

/// Damped Gauss–Newton on the distance-difference residuals from (x, y): the point, the
/// iterations, and whether the step became negligible (converged).
fn gauss_newton(
    a: &[Arrival],
    v: f64,
    mut x: f64,
    mut y: f64,
    max_iter: usize,
    scale: f64,
) -> (f64, f64, u32, bool) {
    let cost = |x: f64, y: f64| lucy(a, v, x, y);
    let mut lambda = 1e-3;
    let mut c = cost(x, y);
    for it in 1..=max_iter {
        // Normal equations JᵀJ δ = −Jᵀr (2×2).
        let (mut a11, mut a12, mut a22, mut g1, mut g2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let d0 = (x - a[0].x).hypot(y - a[0].y).max(1e-12);
        let (u0x, u0y) = ((x - a[0].x) / d0, (y - a[0].y) / d0);
        for k in &a[1..] {
            let dk = (x - k.x).hypot(y - k.y).max(1e-12);
            let r = (dk - d0) - v * (k.t - a[0].t);
            let (jx, jy) = ((x - k.x) / dk - u0x, (y - k.y) / dk - u0y);
            a11 += jx * jx;
            a12 += jx * jy;
            a22 += jy * jy;
            g1 += jx * r;
            g2 += jy * r;
        }
        // Try the step; raise the damping until the cost falls (Levenberg–Marquardt).
        let mut accepted = false;
        for _ in 0..30 {
            let (b11, b22) = (a11 * (1.0 + lambda) + 1e-15, a22 * (1.0 + lambda) + 1e-15);
            let det = b11 * b22 - a12 * a12;
            if det.abs() < 1e-300 {
                lambda *= 10.0;
                continue;
            }
            let dx = -(b22 * g1 - a12 * g2) / det;
            let dy = -(b11 * g2 - a12 * g1) / det;
            let (nx, ny) = (x + dx, y + dy);
            let nc = cost(nx, ny);
            if nc.is_finite() && nc <= c {
                let step = dx.hypot(dy);
                x = nx;
                y = ny;
                c = nc;
                lambda = (lambda / 10.0).max(1e-12);
                accepted = true;
                if step < 1e-9 * scale {
                    return (x, y, it as u32, true);
                }
                break;
            }
            lambda *= 10.0;
        }
        if !accepted {
            // No step lowers the cost: a minimum (to the precision of the arithmetic).
            return (x, y, it as u32, true);
        }
    }
    (x, y, max_iter as u32, false)
}

/// Planar location from arrivals sorted by arrival (at least 3 at distinct places).
pub fn planar(a: &[Arrival], v: f64, max_iter: usize) -> Option<Location> {
    if a.is_empty() {
        return None;
    }
    let distinct = {
        let mut p: Vec<(f64, f64)> = a.iter().map(|k| (k.x, k.y)).collect();
        p.sort_by(|u, w| u.0.total_cmp(&w.0).then(u.1.total_cmp(&w.1)));
        p.dedup();
        p.len()
    };
    if distinct < 3 {
        return Some(Location {
            x: a[0].x,
            y: Some(a[0].y),
            lucy: 0.0,
            iterations: 0,
            status: Status::TooFewHits,
        });
    }
    let n = a.len() as f64;
    let (cx, cy) = (
        a.iter().map(|k| k.x).sum::<f64>() / n,
        a.iter().map(|k| k.y).sum::<f64>() / n,
    );
    let (x0, x1) = a
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), k| {
            (lo.min(k.x), hi.max(k.x))
        });
    let (y0, y1) = a
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), k| {
            (lo.min(k.y), hi.max(k.y))
        });
    let scale = (x1 - x0).max(y1 - y0).max(1e-9);
    let (x, y, it, ok) = gauss_newton(a, v, cx, cy, max_iter, scale);
    // The best point of a 101 × 101 grid over twice the sensors' box: a check that the
    // iteration from the centroid did not stop in a worse basin (distance differences have
    // saddles, e.g. near a sensor), and the start of the fallback.
    let (gx0, gy0) = ((x0 + x1) / 2.0 - scale, (y0 + y1) / 2.0 - scale);
    let step = 2.0 * scale / 100.0;
    let mut best = (f64::INFINITY, cx, cy);
    for i in 0..=100 {
        for j in 0..=100 {
            let (px, py) = (gx0 + i as f64 * step, gy0 + j as f64 * step);
            let c = lucy(a, v, px, py);
            if c < best.0 {
                best = (c, px, py);
            }
        }
    }
    let inside =
        |x: f64, y: f64| x >= x0 - scale && x <= x1 + scale && y >= y0 - scale && y <= y1 + scale;
    let c = lucy(a, v, x, y);
    if ok && inside(x, y) && c <= best.0 {
        return Some(Location {
            x,
            y: Some(y),
            lucy: c,
            iterations: it,
            status: Status::Located,
        });
    }
    let (fx, fy, it2, _) = gauss_newton(a, v, best.1, best.2, max_iter, scale);
    let fc = lucy(a, v, fx, fy);
    // The better of the two (the fallback may only match the first).
    let (x, y, c) = if fc < c || !ok || !inside(x, y) {
        (fx, fy, fc)
    } else {
        (x, y, c)
    };
    Some(Location {
        x,
        y: Some(y),
        lucy: c,
        iterations: it + it2,
        status: Status::Fallback,
    })
}

/// Locate by kind.
pub fn locate(kind: LocationKind, a: &[Arrival], v: f64, max_iter: usize) -> Option<Location> {
    match kind {
        LocationKind::Linear => linear(a, v),
        LocationKind::Planar => planar(a, v, max_iter),
    }
}

/// Whether a location lies in the zone (a polygon by ray casting; its boundary counts as
/// inside only where the crossing rule puts it).
pub fn in_zone(z: &ZoneSpec, x: f64, y: f64) -> bool {
    match z {
        ZoneSpec::Interval([a, b]) => x >= *a && x <= *b,
        ZoneSpec::Polygon(p) => {
            let mut inside = false;
            let mut j = p.len() - 1;
            for i in 0..p.len() {
                let ([xi, yi], [xj, yj]) = (p[i], p[j]);
                if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
                    inside = !inside;
                }
                j = i;
            }
            inside
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Arrivals at sensors from a source at (sx, sy) emitting at t0, sorted by arrival.
    fn arrivals(sensors: &[(f64, f64)], sx: f64, sy: f64, v: f64) -> Vec<Arrival> {
        let mut a: Vec<Arrival> = sensors
            .iter()
            .map(|&(x, y)| Arrival {
                x,
                y,
                t: 1.0 + (x - sx).hypot(y - sy) / v,
            })
            .collect();
        a.sort_by(|p, q| p.t.total_cmp(&q.t));
        a
    }

    #[test]
    fn linear_gives_the_analytic_point_and_clamps_beyond() {
        let s = [(-0.035, 0.0), (0.035, 0.0)];
        for sx in [-0.03, -0.004, 0.0, 0.0123, 0.034] {
            let l = linear(&arrivals(&s, sx, 0.0, 2500.0), 2500.0).unwrap();
            assert!((l.x - sx).abs() < 1e-12, "{sx}: {l:?}");
            assert_eq!(l.status, Status::Located);
            assert!(l.lucy < 1e-12);
        }
        // A grip source at 0.05, beyond the sensor at 0.035: clamped there, flagged; an
        // arrival difference longer than L (noise) clamps too.
        let l = linear(&arrivals(&s, 0.05, 0.0, 2500.0), 2500.0).unwrap();
        assert!((l.x - 0.035).abs() < 1e-12, "{l:?}");
        let mut a = arrivals(&s, 0.05, 0.0, 2500.0);
        a[1].t += 2e-6;
        let l = linear(&a, 2500.0).unwrap();
        assert_eq!((l.x, l.status), (0.035, Status::BeyondSensor));
        assert!((l.lucy - 2500.0 * 2e-6).abs() < 1e-9);
        assert_eq!(linear(&a[..1], 2500.0).unwrap().status, Status::TooFewHits);
    }

    #[test]
    fn planar_finds_sources_inside_and_outside_the_array() {
        let s = [(0.6, 0.6), (0.15, 0.6), (0.15, 0.15), (0.6, 0.15)];
        for (sx, sy) in [
            (0.22, 0.37),
            (0.5, 0.2),
            (0.375, 0.375),
            (0.7, 0.3),
            (0.16, 0.59),
        ] {
            let l = planar(&arrivals(&s, sx, sy, 5000.0), 5000.0, 50).unwrap();
            let err = (l.x - sx).hypot(l.y.unwrap() - sy);
            assert!(err < 1e-6, "({sx}, {sy}): {l:?}");
            assert_ne!(l.status, Status::TooFewHits);
            assert!(l.lucy < 1e-6);
        }
        // Three sensors determine the point too.
        let l = planar(&arrivals(&s[..3], 0.3, 0.4, 5000.0), 5000.0, 50).unwrap();
        assert!((l.x - 0.3).hypot(l.y.unwrap() - 0.4) < 1e-6, "{l:?}");
        // Two places are too few.
        let l = planar(&arrivals(&s[..2], 0.3, 0.4, 5000.0), 5000.0, 50).unwrap();
        assert_eq!(l.status, Status::TooFewHits);
    }

    #[test]
    fn zones() {
        assert!(in_zone(&ZoneSpec::Interval([-0.03, 0.03]), 0.0, 0.0));
        assert!(!in_zone(&ZoneSpec::Interval([-0.03, 0.03]), 0.035, 0.0));
        let sq = ZoneSpec::Polygon(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
        assert!(in_zone(&sq, 0.5, 0.5));
        assert!(!in_zone(&sq, 1.5, 0.5));
        let tri = ZoneSpec::Polygon(vec![[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]]);
        assert!(in_zone(&tri, 0.5, 0.5) && !in_zone(&tri, 1.5, 1.5));
    }
}

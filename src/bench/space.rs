//! The simulator's third dimension measured: the 3-D acoustic field alone at growing sizes,
//! and the 3-D scenarios (with the plane fine-grid fibre failure beside them) end to end at
//! each cell size asked — wall time, peak memory and cells.

use super::BenchError;
use crate::util::rss_bytes;

/// One size of the 3-D field bench.
#[derive(Debug, Clone)]
pub struct Field3dRow {
    /// Cells per side.
    pub n: usize,
    pub steps: usize,
    pub seconds: f64,
    /// The process's resident memory with this size's field still held, bytes.
    pub rss: u64,
    /// What the field's four arrays hold, bytes.
    pub field_bytes: u64,
}

/// The 3-D acoustic field (4th order, one-way faces, a source at the centre) at n³ cells for
/// each n of `sizes` (ascending), `steps` steps each, on the current rayon pool.
pub fn field3d(sizes: &[usize], steps: usize) -> Result<Vec<Field3dRow>, BenchError> {
    use crate::sim::acoustic3d::{Field3, Grid3};
    let mut sizes = sizes.to_vec();
    sizes.sort_unstable();
    let mut out = Vec::new();
    for n in sizes {
        let g = Grid3::cube(n, 1.0, 0.45, 1.0, 1.0);
        let mut f = Field3::new(&g).map_err(BenchError::run)?;
        let t0 = std::time::Instant::now();
        for s in 0..steps {
            f.add_source(n / 2, n / 2, n / 2, (s as f64 * 0.2).sin());
            f.step();
        }
        let seconds = t0.elapsed().as_secs_f64();
        std::hint::black_box(f.energy());
        // Measured while `f` is alive: what this size holds, not an earlier stage's peak.
        out.push(Field3dRow {
            n,
            steps,
            seconds,
            rss: rss_bytes().unwrap_or(0),
            field_bytes: (4 * n * n * n * 8) as u64,
        });
    }
    Ok(out)
}

/// One scenario at one cell size: the 3-D bench's row.
#[derive(Debug, Clone)]
pub struct Network3dRow {
    pub scenario: String,
    pub grid_um: f64,
    /// nx × ny (× nz).
    pub cells: usize,
    pub acoustic_steps: usize,
    pub seconds: f64,
    /// Peak resident memory during this run alone (the mark reset before it), bytes.
    pub peak_rss: u64,
}

/// The 3-D scenarios (`network3d-bond-failure`, `network3d-fibre-failure`) and the plane
/// `structure2x1-fibre-failure` at each cell size of `grid_um` (µm), end to end as
/// `aepipe simulate` runs them: relaxation, 4 000 implicit steps and the field's steps.
pub fn network3d(grid_um: &[f64]) -> Result<Vec<Network3dRow>, BenchError> {
    let mut out = Vec::new();
    for &um in grid_um {
        for name in [
            "network3d-bond-failure",
            "network3d-fibre-failure",
            "structure2x1-fibre-failure",
        ] {
            let p = crate::sim::scenario::Params(vec![("grid_um".into(), um)]);
            let m = crate::sim::scenario::build(name, &p).map_err(BenchError::run)?;
            let g = m.grid.as_ref().expect("the scenarios have a grid");
            let cells = g.nx * g.ny * g.z.map_or(1, |z| z.nz);
            let acoustic_steps = (m.system.iterations as f64 * m.system.dt / g.dt).round() as usize;
            crate::util::reset_peak_rss();
            let t0 = std::time::Instant::now();
            crate::sim::simulate(&m, &Default::default()).map_err(BenchError::run)?;
            out.push(Network3dRow {
                scenario: name.into(),
                grid_um: um,
                cells,
                acoustic_steps,
                seconds: t0.elapsed().as_secs_f64(),
                peak_rss: crate::util::peak_rss_bytes().unwrap_or(0),
            });
        }
    }
    Ok(out)
}

//! Model files: the thesis's sectioned text format (Appendix A) and its TOML equivalent.
//!
//! The sectioned format is a list of `Section NAME` … `End NAME` blocks; inside, the first
//! line names the columns and each further line is one row (tabs or spaces). Every problem is
//! reported with its line number.

use super::model::*;
use super::SimError;
use std::path::Path;

/// Read a model from `path`: `.toml` as TOML, anything else as the sectioned format.
pub fn read_model(path: &Path) -> Result<ModelFile, SimError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SimError::Read(format!("{}: {e}", path.display())))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "simulation".into());
    let model = if path.extension().is_some_and(|e| e == "toml") {
        toml::from_str::<ModelFile>(&text).map_err(|e| {
            let line = e
                .span()
                .map(|s| text[..s.start].matches('\n').count() + 1)
                .unwrap_or(0);
            SimError::Parse {
                path: path.display().to_string(),
                line,
                message: e.message().to_string(),
            }
        })?
    } else {
        let mut m = parse_sectioned(&text, &path.display().to_string())?;
        m.name = name;
        m
    };
    model.check().map_err(|e| match e {
        SimError::Model(m) => SimError::Model(format!("{}: {m}", path.display())),
        other => other,
    })?;
    Ok(model)
}

struct Table {
    header: Vec<String>,
    rows: Vec<(usize, Vec<String>)>,
    line: usize,
}

impl Table {
    fn col(&self, names: &[&str]) -> Option<usize> {
        self.header
            .iter()
            .position(|h| names.iter().any(|n| h.eq_ignore_ascii_case(n)))
    }
}

type Row = (usize, Vec<String>);

/// The sections read from a file, and how to read their cells (every error names the file
/// and the line).
struct Sections<'a> {
    path: &'a str,
    tables: Vec<(String, Table)>,
}

/// The sections of Appendix A; the drawing and storage ones are accepted and ignored.
const KNOWN: &[&str] = &[
    "System",
    "Nodes",
    "Springs",
    "Initial",
    "Force",
    "NodeDamage",
    "Grid",
    "Storage",
    "Sensor",
    "DrawNode",
    "DrawGrid",
    "DrawKey",
    "DrawTension",
    "DrawForce",
];

impl<'a> Sections<'a> {
    fn err(&self, line: usize, message: String) -> SimError {
        SimError::Parse {
            path: self.path.to_string(),
            line,
            message,
        }
    }

    /// Split the text into `Section NAME` … `End NAME` tables: a header line, then rows.
    fn read(text: &str, path: &'a str) -> Result<Sections<'a>, SimError> {
        let mut s = Sections {
            path,
            tables: Vec::new(),
        };
        let mut current: Option<(String, Table)> = None;
        for (k, raw) in text.lines().enumerate() {
            let ln = k + 1;
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() || line.chars().all(|c| c == '-' || c.is_whitespace()) {
                continue;
            }
            let words: Vec<String> = line.split_whitespace().map(str::to_string).collect();
            if words[0] == "Section" {
                if let Some((name, _)) = &current {
                    return Err(s.err(
                        ln,
                        format!("Section inside Section {name} (missing End {name})"),
                    ));
                }
                let name = words
                    .get(1)
                    .ok_or_else(|| s.err(ln, "Section without a name".into()))?
                    .clone();
                current = Some((
                    name,
                    Table {
                        header: vec![],
                        rows: vec![],
                        line: ln,
                    },
                ));
            } else if words[0] == "End" {
                let (name, table) = current
                    .take()
                    .ok_or_else(|| s.err(ln, "End without Section".into()))?;
                if words.get(1) != Some(&name) {
                    return Err(s.err(
                        ln,
                        format!(
                            "End {} closes Section {name}",
                            words.get(1).map(String::as_str).unwrap_or("?")
                        ),
                    ));
                }
                s.tables.push((name, table));
            } else {
                let Some((_, table)) = current.as_mut() else {
                    return Err(s.err(ln, format!("{line:?} outside any Section")));
                };
                if table.header.is_empty() {
                    table.header = words;
                } else {
                    if words.len() != table.header.len() {
                        return Err(s.err(
                            ln,
                            format!(
                                "{} values, the header names {} columns ({})",
                                words.len(),
                                table.header.len(),
                                table.header.join(" ")
                            ),
                        ));
                    }
                    table.rows.push((ln, words));
                }
            }
        }
        if let Some((name, t)) = current {
            return Err(s.err(t.line, format!("Section {name} has no End")));
        }
        for (name, t) in &s.tables {
            if !KNOWN.contains(&name.as_str()) {
                return Err(s.err(
                    t.line,
                    format!("unknown section {name}; known: {}", KNOWN.join(", ")),
                ));
            }
        }
        Ok(s)
    }

    fn get(&self, name: &str) -> Option<&Table> {
        self.tables.iter().find(|(n, _)| n == name).map(|(_, t)| t)
    }

    fn num(&self, t: &Table, row: &Row, names: &[&str]) -> Result<f64, SimError> {
        let c = t
            .col(names)
            .ok_or_else(|| self.err(t.line, format!("no column {} in the header", names[0])))?;
        row.1[c].parse::<f64>().map_err(|_| {
            self.err(
                row.0,
                format!("{}: {:?} is not a number", names[0], row.1[c]),
            )
        })
    }

    /// A number from a column the format leaves optional (the third dimension's): `None`
    /// when the header has no such column.
    fn opt_num(&self, t: &Table, row: &Row, names: &[&str]) -> Result<Option<f64>, SimError> {
        match t.col(names) {
            Some(_) => self.num(t, row, names).map(Some),
            None => Ok(None),
        }
    }

    fn word(&self, t: &Table, row: &Row, names: &[&str]) -> Result<String, SimError> {
        let c = t
            .col(names)
            .ok_or_else(|| self.err(t.line, format!("no column {} in the header", names[0])))?;
        Ok(row.1[c].clone())
    }

    fn index(&self, t: &Table, row: &Row, names: &[&str]) -> Result<usize, SimError> {
        let v = self.num(t, row, names)?;
        if v < 0.0 || v.fract() != 0.0 {
            return Err(self.err(row.0, format!("{}: {v} is not an index", names[0])));
        }
        Ok(v as usize)
    }

    fn boolean(&self, t: &Table, row: &Row, names: &[&str]) -> Result<bool, SimError> {
        match self.word(t, row, names)?.to_ascii_lowercase().as_str() {
            "true" | "1" | "yes" => Ok(true),
            "false" | "0" | "no" => Ok(false),
            w => Err(self.err(row.0, format!("{}: {w:?} is not true/false", names[0]))),
        }
    }
}

/// What Section System says besides the [`System`] itself.
struct SystemFlags {
    gravity: f64,
    runwave: bool,
    stretch: bool,
}

fn parse_system(s: &Sections) -> Result<(System, SystemFlags), SimError> {
    let t = s
        .get("System")
        .ok_or_else(|| s.err(0, "no Section System".into()))?;
    let row = t
        .rows
        .first()
        .ok_or_else(|| s.err(t.line, "Section System has no values".into()))?;
    let solver_word = s.word(t, row, &["solver"])?;
    let solver: Solver = solver_word.parse().map_err(|_| {
        s.err(
            row.0,
            format!("solver {solver_word:?}: expected IEuler, EEuler, RK4 or Verlet"),
        )
    })?;
    let flags = SystemFlags {
        gravity: if t.col(&["gravity"]).is_some() {
            s.num(t, row, &["gravity"])?
        } else {
            0.0
        },
        runwave: t.col(&["runwave"]).is_none() || s.boolean(t, row, &["runwave"])?,
        stretch: t.col(&["stretch"]).is_none() || s.boolean(t, row, &["stretch"])?,
    };
    let system = System {
        dt: s.num(t, row, &["dt"])?,
        damping: s.num(t, row, &["damping"])?,
        iterations: s.index(t, row, &["iters", "iterations"])?,
        solver,
        relax: true,
    };
    Ok((system, flags))
}

fn parse_nodes(s: &Sections) -> Result<Vec<NodeSpec>, SimError> {
    let t = s
        .get("Nodes")
        .ok_or_else(|| s.err(0, "no Section Nodes".into()))?;
    let mut nodes = Vec::new();
    for (k, row) in t.rows.iter().enumerate() {
        let id = s.index(t, row, &["Node"])?;
        if id != k {
            return Err(s.err(
                row.0,
                format!("node {id}: nodes must be numbered 0, 1, 2… in order (expected {k})"),
            ));
        }
        let ty = s.index(t, row, &["type"])?;
        if ty > 1 {
            return Err(s.err(row.0, format!("node type {ty}: 0 = free, 1 = fixed")));
        }
        nodes.push(NodeSpec {
            x: s.num(t, row, &["x"])?,
            y: s.num(t, row, &["y"])?,
            z: s.opt_num(t, row, &["z"])?,
            mass: s.num(t, row, &["m", "mass"])?,
            fixed: ty == 1,
        });
    }
    Ok(nodes)
}

fn parse_springs(s: &Sections) -> Result<Vec<SpringSpec>, SimError> {
    let Some(t) = s.get("Springs") else {
        return Ok(vec![]);
    };
    t.rows
        .iter()
        .map(|row| {
            Ok(SpringSpec {
                a: s.index(t, row, &["N1"])?,
                b: s.index(t, row, &["N2"])?,
                e: s.num(t, row, &["E"])?,
                length: Some(s.num(t, row, &["L"])?),
                t: s.num(t, row, &["t"])?,
                w: s.num(t, row, &["w"])?,
                poisson: s.num(t, row, &["P.Ratio", "nu", "poisson"])?,
                fibre: if t.col(&["Fibre"]).is_some() {
                    s.index(t, row, &["Fibre"])? as u32
                } else {
                    0
                },
            })
        })
        .collect()
}

/// Initial conditions; static ones (type 1) only when the system is stretched.
fn parse_initial(s: &Sections, stretch: bool) -> Result<Vec<InitialSpec>, SimError> {
    let mut initial = Vec::new();
    let Some(t) = s.get("Initial") else {
        return Ok(initial);
    };
    for row in &t.rows {
        let kind = match s.index(t, row, &["type"])? {
            0 => IcKind::Eq,
            1 => IcKind::St,
            k => {
                return Err(s.err(
                    row.0,
                    format!("initial condition type {k}: 0 = EqIC, 1 = StIC"),
                ))
            }
        };
        if kind == IcKind::St && !stretch {
            continue;
        }
        initial.push(InitialSpec {
            node: s.index(t, row, &["Node"])?,
            dx: s.num(t, row, &["dx"])?,
            dy: s.num(t, row, &["dy"])?,
            du: s.num(t, row, &["du"])?,
            dv: s.num(t, row, &["dv"])?,
            dz: s.opt_num(t, row, &["dz"])?.unwrap_or(0.0),
            dw: s.opt_num(t, row, &["dw"])?.unwrap_or(0.0),
            kind,
        });
    }
    Ok(initial)
}

/// Forces, and gravity as a constant force on every node.
fn parse_forces(
    s: &Sections,
    nodes: &[NodeSpec],
    gravity: f64,
) -> Result<Vec<ForceSpec>, SimError> {
    let mut forces = Vec::new();
    if let Some(t) = s.get("Force") {
        for row in &t.rows {
            forces.push(ForceSpec {
                node: s.index(t, row, &["Node"])?,
                fx: s.num(t, row, &["Fx"])?,
                fy: s.num(t, row, &["Fy"])?,
                fz: s.opt_num(t, row, &["Fz"])?.unwrap_or(0.0),
                start: s.num(t, row, &["Start"])?,
                finish: s.num(t, row, &["Finish"])?,
            });
        }
    }
    if gravity != 0.0 {
        for (i, nd) in nodes.iter().enumerate() {
            forces.push(ForceSpec {
                node: i,
                fx: 0.0,
                fy: -gravity * nd.mass,
                fz: 0.0,
                start: f64::NEG_INFINITY,
                finish: f64::INFINITY,
            });
        }
    }
    Ok(forces)
}

fn parse_damage(s: &Sections, springs: &[SpringSpec]) -> Result<Vec<DamageSpec>, SimError> {
    let mut damage = Vec::new();
    let Some(t) = s.get("NodeDamage") else {
        return Ok(damage);
    };
    for row in &t.rows {
        let node = s.index(t, row, &["Node"])?;
        let time = s.num(t, row, &["When", "time"])?;
        let kind = s.word(t, row, &["Type"])?;
        match kind.to_ascii_lowercase().as_str() {
            "0" | "bond" => damage.push(DamageSpec::Bond { node, time }),
            "1" | "fibre" | "fiber" => {
                let spring = s.index(t, row, &["Option", "spring"])?;
                if let Some(sp) = springs.get(spring) {
                    if sp.a != node && sp.b != node {
                        return Err(s.err(
                            row.0,
                            format!("fibre failure: spring {spring} does not touch node {node}"),
                        ));
                    }
                }
                damage.push(DamageSpec::Fibre { spring, time });
            }
            _ => return Err(s.err(row.0, format!("damage type {kind:?}: 0/bond or 1/fibre"))),
        }
    }
    Ok(damage)
}

/// The acoustic grid and its sensors (read only when the system runs the wave).
fn parse_grid(
    s: &Sections,
    runwave: bool,
) -> Result<(Option<GridSpec>, Vec<SensorSpec>), SimError> {
    let Some(t) = s.get("Grid") else {
        return Ok((None, vec![]));
    };
    let (Some(row), true) = (t.rows.first(), runwave) else {
        return Ok((None, vec![]));
    };
    let dt = s.num(t, row, &["dt"])?;
    if t.col(&["ts"]).is_some() {
        let ts = s.num(t, row, &["ts"])?;
        if (ts - dt).abs() > 1e-9 * dt {
            return Err(s.err(
                row.0,
                format!("sampling interval ts = {ts:e} must equal the grid dt = {dt:e}"),
            ));
        }
    }
    let method = s.word(t, row, &["Method"])?;
    let order = match method.to_ascii_lowercase().as_str() {
        "acoustic02" | "acoustic2" | "2" => Order::Second,
        "acoustic04" | "acoustic4" | "4" => Order::Fourth,
        _ => {
            return Err(s.err(
                row.0,
                format!("method {method:?}: acoustic02 or acoustic04"),
            ))
        }
    };
    let grid = GridSpec {
        x1: s.num(t, row, &["x1"])?,
        x2: s.num(t, row, &["x2"])?,
        y1: s.num(t, row, &["y1"])?,
        y2: s.num(t, row, &["y2"])?,
        nx: s.index(t, row, &["Nx"])?,
        ny: s.index(t, row, &["Ny"])?,
        dt,
        rho: s.num(t, row, &["rho"])?,
        c: s.num(t, row, &["c"])?,
        order,
        dipole_m: None,
        z: match t.col(&["Nz"]) {
            None => None,
            Some(_) => Some(ZAxis {
                z1: s.num(t, row, &["z1"])?,
                z2: s.num(t, row, &["z2"])?,
                nz: s.index(t, row, &["Nz"])?,
            }),
        },
    };
    let mut sensors = Vec::new();
    if let Some(st) = s.get("Sensor") {
        for row in &st.rows {
            sensors.push(SensorSpec {
                i: s.index(st, row, &["X"])?,
                j: s.index(st, row, &["Y"])?,
                k: match st.col(&["Z"]) {
                    Some(_) => Some(s.index(st, row, &["Z"])?),
                    None => None,
                },
            });
        }
    }
    Ok((Some(grid), sensors))
}

/// Parse the sectioned format of Appendix A: one function per section.
pub fn parse_sectioned(text: &str, path: &str) -> Result<ModelFile, SimError> {
    let s = Sections::read(text, path)?;
    let (system, flags) = parse_system(&s)?;
    let nodes = parse_nodes(&s)?;
    let springs = parse_springs(&s)?;
    let initial = parse_initial(&s, flags.stretch)?;
    let forces = parse_forces(&s, &nodes, flags.gravity)?;
    let damage = parse_damage(&s, &springs)?;
    let (grid, sensors) = parse_grid(&s, flags.runwave)?;
    Ok(ModelFile {
        name: "simulation".into(),
        label: None,
        system,
        nodes,
        springs,
        initial,
        forces,
        damage,
        grid,
        sensors,
    })
}

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

/// Parse the sectioned format of Appendix A.
pub fn parse_sectioned(text: &str, path: &str) -> Result<ModelFile, SimError> {
    let err = |line: usize, message: String| SimError::Parse {
        path: path.to_string(),
        line,
        message,
    };
    let mut sections: Vec<(String, Table)> = Vec::new();
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
                return Err(err(
                    ln,
                    format!("Section inside Section {name} (missing End {name})"),
                ));
            }
            let name = words
                .get(1)
                .ok_or_else(|| err(ln, "Section without a name".into()))?
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
                .ok_or_else(|| err(ln, "End without Section".into()))?;
            if words.get(1) != Some(&name) {
                return Err(err(
                    ln,
                    format!(
                        "End {} closes Section {name}",
                        words.get(1).map(String::as_str).unwrap_or("?")
                    ),
                ));
            }
            sections.push((name, table));
        } else {
            let (_, table) = current
                .as_mut()
                .ok_or_else(|| err(ln, format!("{line:?} outside any Section")))?;
            if table.header.is_empty() {
                table.header = words;
            } else {
                if words.len() != table.header.len() {
                    return Err(err(
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
        return Err(err(t.line, format!("Section {name} has no End")));
    }
    let get = |name: &str| sections.iter().find(|(n, _)| n == name).map(|(_, t)| t);
    for (name, t) in &sections {
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
        if !KNOWN.contains(&name.as_str()) {
            return Err(err(
                t.line,
                format!("unknown section {name}; known: {}", KNOWN.join(", ")),
            ));
        }
    }
    let num = |t: &Table, row: &(usize, Vec<String>), names: &[&str]| -> Result<f64, SimError> {
        let c = t
            .col(names)
            .ok_or_else(|| err(t.line, format!("no column {} in the header", names[0])))?;
        row.1[c].parse::<f64>().map_err(|_| {
            err(
                row.0,
                format!("{}: {:?} is not a number", names[0], row.1[c]),
            )
        })
    };
    let word =
        |t: &Table, row: &(usize, Vec<String>), names: &[&str]| -> Result<String, SimError> {
            let c = t
                .col(names)
                .ok_or_else(|| err(t.line, format!("no column {} in the header", names[0])))?;
            Ok(row.1[c].clone())
        };
    let index =
        |t: &Table, row: &(usize, Vec<String>), names: &[&str]| -> Result<usize, SimError> {
            let v = num(t, row, names)?;
            if v < 0.0 || v.fract() != 0.0 {
                return Err(err(row.0, format!("{}: {v} is not an index", names[0])));
            }
            Ok(v as usize)
        };
    let boolean =
        |t: &Table, row: &(usize, Vec<String>), names: &[&str]| -> Result<bool, SimError> {
            match word(t, row, names)?.to_ascii_lowercase().as_str() {
                "true" | "1" | "yes" => Ok(true),
                "false" | "0" | "no" => Ok(false),
                w => Err(err(row.0, format!("{}: {w:?} is not true/false", names[0]))),
            }
        };

    let sys_t = get("System").ok_or_else(|| err(0, "no Section System".into()))?;
    let sys_row = sys_t
        .rows
        .first()
        .ok_or_else(|| err(sys_t.line, "Section System has no values".into()))?;
    let solver_word = word(sys_t, sys_row, &["solver"])?;
    let solver = match solver_word.to_ascii_lowercase().as_str() {
        "ieuler" | "implicit" | "implicit-euler" => Solver::ImplicitEuler,
        "eeuler" | "euler" | "explicit-euler" => Solver::ExplicitEuler,
        "rk4" => Solver::Rk4,
        "verlet" | "vverlet" | "velocity-verlet" => Solver::Verlet,
        _ => {
            return Err(err(
                sys_row.0,
                format!("solver {solver_word:?}: expected IEuler, EEuler, RK4 or Verlet"),
            ))
        }
    };
    let gravity = if sys_t.col(&["gravity"]).is_some() {
        num(sys_t, sys_row, &["gravity"])?
    } else {
        0.0
    };
    let runwave = sys_t.col(&["runwave"]).is_none() || boolean(sys_t, sys_row, &["runwave"])?;
    let stretch = sys_t.col(&["stretch"]).is_none() || boolean(sys_t, sys_row, &["stretch"])?;
    let system = System {
        dt: num(sys_t, sys_row, &["dt"])?,
        damping: num(sys_t, sys_row, &["damping"])?,
        iterations: index(sys_t, sys_row, &["iters", "iterations"])?,
        solver,
        relax: true,
    };

    let nodes_t = get("Nodes").ok_or_else(|| err(0, "no Section Nodes".into()))?;
    let mut nodes = Vec::new();
    for (k, row) in nodes_t.rows.iter().enumerate() {
        let id = index(nodes_t, row, &["Node"])?;
        if id != k {
            return Err(err(
                row.0,
                format!("node {id}: nodes must be numbered 0, 1, 2… in order (expected {k})"),
            ));
        }
        let ty = index(nodes_t, row, &["type"])?;
        if ty > 1 {
            return Err(err(row.0, format!("node type {ty}: 0 = free, 1 = fixed")));
        }
        nodes.push(NodeSpec {
            x: num(nodes_t, row, &["x"])?,
            y: num(nodes_t, row, &["y"])?,
            mass: num(nodes_t, row, &["m", "mass"])?,
            fixed: ty == 1,
        });
    }
    let mut springs = Vec::new();
    if let Some(t) = get("Springs") {
        for row in &t.rows {
            springs.push(SpringSpec {
                a: index(t, row, &["N1"])?,
                b: index(t, row, &["N2"])?,
                e: num(t, row, &["E"])?,
                length: Some(num(t, row, &["L"])?),
                t: num(t, row, &["t"])?,
                w: num(t, row, &["w"])?,
                poisson: num(t, row, &["P.Ratio", "nu", "poisson"])?,
                fibre: if t.col(&["Fibre"]).is_some() {
                    index(t, row, &["Fibre"])? as u32
                } else {
                    0
                },
            });
        }
    }
    let mut initial = Vec::new();
    if let Some(t) = get("Initial") {
        for row in &t.rows {
            let kind = match index(t, row, &["type"])? {
                0 => IcKind::Eq,
                1 => IcKind::St,
                k => {
                    return Err(err(
                        row.0,
                        format!("initial condition type {k}: 0 = EqIC, 1 = StIC"),
                    ))
                }
            };
            if kind == IcKind::St && !stretch {
                continue;
            }
            initial.push(InitialSpec {
                node: index(t, row, &["Node"])?,
                dx: num(t, row, &["dx"])?,
                dy: num(t, row, &["dy"])?,
                du: num(t, row, &["du"])?,
                dv: num(t, row, &["dv"])?,
                kind,
            });
        }
    }
    let mut forces = Vec::new();
    if let Some(t) = get("Force") {
        for row in &t.rows {
            forces.push(ForceSpec {
                node: index(t, row, &["Node"])?,
                fx: num(t, row, &["Fx"])?,
                fy: num(t, row, &["Fy"])?,
                start: num(t, row, &["Start"])?,
                finish: num(t, row, &["Finish"])?,
            });
        }
    }
    if gravity != 0.0 {
        for (i, nd) in nodes.iter().enumerate() {
            forces.push(ForceSpec {
                node: i,
                fx: 0.0,
                fy: -gravity * nd.mass,
                start: f64::NEG_INFINITY,
                finish: f64::INFINITY,
            });
        }
    }
    let mut damage = Vec::new();
    if let Some(t) = get("NodeDamage") {
        for row in &t.rows {
            let node = index(t, row, &["Node"])?;
            let time = num(t, row, &["When", "time"])?;
            let kind = word(t, row, &["Type"])?;
            match kind.to_ascii_lowercase().as_str() {
                "0" | "bond" => damage.push(DamageSpec::Bond { node, time }),
                "1" | "fibre" | "fiber" => {
                    let spring = index(t, row, &["Option", "spring"])?;
                    if let Some(s) = springs.get(spring) {
                        if s.a != node && s.b != node {
                            return Err(err(
                                row.0,
                                format!(
                                    "fibre failure: spring {spring} does not touch node {node}"
                                ),
                            ));
                        }
                    }
                    damage.push(DamageSpec::Fibre { spring, time });
                }
                _ => {
                    return Err(err(
                        row.0,
                        format!("damage type {kind:?}: 0/bond or 1/fibre"),
                    ))
                }
            }
        }
    }
    let mut grid = None;
    let mut sensors = Vec::new();
    if let Some(t) = get("Grid") {
        if let (Some(row), true) = (t.rows.first(), runwave) {
            let dt = num(t, row, &["dt"])?;
            if t.col(&["ts"]).is_some() {
                let ts = num(t, row, &["ts"])?;
                if (ts - dt).abs() > 1e-9 * dt {
                    return Err(err(
                        row.0,
                        format!("sampling interval ts = {ts:e} must equal the grid dt = {dt:e}"),
                    ));
                }
            }
            let method = word(t, row, &["Method"])?;
            let order = match method.to_ascii_lowercase().as_str() {
                "acoustic02" | "acoustic2" | "2" => Order::Second,
                "acoustic04" | "acoustic4" | "4" => Order::Fourth,
                _ => {
                    return Err(err(
                        row.0,
                        format!("method {method:?}: acoustic02 or acoustic04"),
                    ))
                }
            };
            grid = Some(GridSpec {
                x1: num(t, row, &["x1"])?,
                x2: num(t, row, &["x2"])?,
                y1: num(t, row, &["y1"])?,
                y2: num(t, row, &["y2"])?,
                nx: index(t, row, &["Nx"])?,
                ny: index(t, row, &["Ny"])?,
                dt,
                rho: num(t, row, &["rho"])?,
                c: num(t, row, &["c"])?,
                order,
            });
            if let Some(s) = get("Sensor") {
                for row in &s.rows {
                    sensors.push(SensorSpec {
                        i: index(s, row, &["X"])?,
                        j: index(s, row, &["Y"])?,
                    });
                }
            }
        }
    }
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

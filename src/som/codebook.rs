//! A map in files: the SOM_PAK codebook (`.cod`) written and read, and the checks of a map
//! read from a file (`model.json`, or a codebook), whose sizes are claims bounded before
//! anything is allocated.

use super::{Som, SomError, SomParams};

/// The largest map a model file may describe (nodes, and values of the codebook): a header
/// or `model.json` claiming more is refused before anything is allocated.
pub const MAX_MAP_NODES: usize = 1_000_000;
pub const MAX_CODEBOOK_VALUES: usize = 100_000_000;

/// Nodes of a `rows × cols` map of `dim`-vectors, if the sizes are sane.
fn check_map_size(dim: usize, rows: usize, cols: usize) -> Result<usize, String> {
    if dim == 0 || rows == 0 || cols == 0 {
        return Err(format!("a {cols}×{rows} map of {dim}-vectors is empty"));
    }
    let nodes = rows
        .checked_mul(cols)
        .filter(|&n| n <= MAX_MAP_NODES)
        .ok_or_else(|| format!("a {cols}×{rows} map exceeds {MAX_MAP_NODES} nodes"))?;
    nodes
        .checked_mul(dim)
        .filter(|&v| v <= MAX_CODEBOOK_VALUES)
        .ok_or_else(|| {
            format!("{nodes} nodes × {dim} values exceed {MAX_CODEBOOK_VALUES} codebook values")
        })?;
    Ok(nodes)
}

impl Som {
    /// SOM_PAK codebook (`.cod`): header `dim rect cols rows gaussian`, then one node per line,
    /// x (column) fastest, with its label if any.
    pub fn to_cod(&self) -> String {
        let mut s = format!("{} rect {} {} gaussian\n", self.dim, self.cols, self.rows);
        for j in 0..self.nodes() {
            let v: Vec<String> = self.node(j).iter().map(|w| format!("{w:e}")).collect();
            s.push_str(&v.join(" "));
            if let Some(l) = self.labels.get(j) {
                s.push(' ');
                s.push_str(l);
            }
            s.push('\n');
        }
        s
    }

    /// Check a map read from a file (`model.json`): sizes within the limits, as many weights
    /// and labels as nodes, every weight finite.
    pub fn check(&self) -> Result<(), SomError> {
        let nodes = check_map_size(self.dim, self.rows, self.cols).map_err(SomError::Data)?;
        if self.weights.len() != nodes * self.dim {
            return Err(SomError::Data(format!(
                "{} weights for {nodes} nodes of {} values",
                self.weights.len(),
                self.dim
            )));
        }
        if !self.labels.is_empty() && self.labels.len() != nodes {
            return Err(SomError::Data(format!(
                "{} node labels for {nodes} nodes",
                self.labels.len()
            )));
        }
        if self.weights.iter().any(|w| !w.is_finite()) {
            return Err(SomError::Data("a weight is not a finite number".into()));
        }
        Ok(())
    }

    /// Read a SOM_PAK codebook (rectangular topology).
    pub fn from_cod(text: &str) -> Result<Som, SomError> {
        Som::parse_cod(text).map_err(SomError::Codebook)
    }

    fn parse_cod(text: &str) -> Result<Som, String> {
        let mut lines = text
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
        let head: Vec<&str> = lines
            .next()
            .ok_or("empty codebook")?
            .split_whitespace()
            .collect();
        if head.len() < 4 || head[1] != "rect" {
            return Err(format!(
                "header '{}': expected 'DIM rect XDIM YDIM [neighbourhood]'",
                head.join(" ")
            ));
        }
        let num = |s: &str, what: &str| {
            s.parse::<usize>()
                .map_err(|_| format!("{what} '{s}' is not a whole number"))
        };
        let (dim, cols, rows) = (
            num(head[0], "dimension")?,
            num(head[2], "x size")?,
            num(head[3], "y size")?,
        );
        // The header is a claim: the sizes are checked, never reserved.
        let nodes = check_map_size(dim, rows, cols)?;
        let mut weights = Vec::new();
        let mut labels = Vec::new();
        for (k, l) in lines.enumerate() {
            let t: Vec<&str> = l.split_whitespace().collect();
            if t.len() < dim {
                return Err(format!("node {}: {} values, need {dim}", k + 1, t.len()));
            }
            for v in &t[..dim] {
                weights.push(
                    v.parse::<f64>()
                        .map_err(|_| format!("node {}: '{v}' is not a number", k + 1))?,
                );
            }
            if t.len() > dim {
                labels.push(t[dim].to_string());
            }
        }
        if weights.len() != dim * nodes {
            return Err(format!(
                "{} nodes, header says {}×{}",
                weights.len() / dim.max(1),
                cols,
                rows
            ));
        }
        if !labels.is_empty() && labels.len() != nodes {
            return Err("some nodes are labelled and some are not".into());
        }
        if weights.iter().any(|w| !w.is_finite()) {
            return Err("a weight is not a finite number".into());
        }
        Ok(Som {
            rows,
            cols,
            dim,
            weights,
            labels,
            params: SomParams {
                rows,
                cols,
                ..SomParams::default()
            },
            log: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn malformed_codebooks_say_why() {
        assert!(Som::from_cod("2 hexa 2 2 gaussian\n")
            .unwrap_err()
            .to_string()
            .contains("rect"));
        assert!(Som::from_cod("2 rect 1 1 gaussian\n1.0 x\n")
            .unwrap_err()
            .to_string()
            .contains("node 1"));
        assert!(Som::from_cod("2 rect 2 1 gaussian\n1 2\n")
            .unwrap_err()
            .to_string()
            .contains("1 nodes"));
    }
}

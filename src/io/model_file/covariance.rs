//! `[covariance]` of a calibrated model file: the covariance of the identified parameters, what
//! a later check of the calibration or an update from a few poses starts from.
//!
//! ```toml
//! [covariance]
//! sigma0 = 1.02                       # a-posteriori σ of unit weight the matrix was scaled by
//! parameters = ["mx", "my", "1-2.wy"] # the identified parameters, in the order of the matrix
//! units = ["mm", "mm", "rad"]         # each parameter's unit: always mm and rad
//! matrix = [
//!     [1.0e-4, 2.0e-6, 0.0],
//!     [2.0e-6, 1.1e-4, 0.0],
//!     [0.0, 0.0, 3.0e-9],
//! ]
//! [covariance.held]                   # every other parameter of the model, and why
//! "0-1.vx" = "redundant"
//! ```
//!
//! The parameters are the error coordinates of the model this file builds ([`ModelFile::build`],
//! frames included) about the geometry the file holds; entry `(i, j)` is in
//! `units[i]·units[j]` whatever the file's `[units]`, so that it reads back exactly. The
//! measurement noise the identification was weighted by is the file's `[noise]`.
use super::write::{num, quote};
use super::*;
use nalgebra::DMatrix;
use std::collections::BTreeMap;

/// Why a parameter of a calibrated model has no row in its [`Covariance`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Held {
    /// Not free in the calibration (`[calibration] fixed`, or held by the assembly).
    #[serde(rename = "fixed")]
    Fixed,
    /// A combination of identified parameters (or without effect on the data): kept as drawn.
    #[serde(rename = "redundant")]
    Redundant,
    /// Of full rank but seen too weakly by the data to fix: held as drawn.
    #[serde(rename = "weak")]
    Weak,
    /// Where the machine stands, which no instrument of the data sees: held as drawn.
    #[serde(rename = "placement")]
    Placement,
}

impl Held {
    /// The word written in the file.
    pub fn word(self) -> &'static str {
        match self {
            Held::Fixed => "fixed",
            Held::Redundant => "redundant",
            Held::Weak => "weak",
            Held::Placement => "placement",
        }
    }
}

/// `[covariance]`: the covariance of a calibration's identified parameters (kinecal's units, mm
/// and rad), `σ̂₀²·(AᵀA)⁻¹` of the identification ([`crate::identify::Identification::covariance`]
/// on the identified parameters).
#[derive(Debug, Clone, PartialEq)]
pub struct Covariance {
    /// The identified parameters' names, in the order of [`Self::matrix`].
    pub names: Vec<String>,
    /// Each parameter's unit (`Length`: mm, `Angle`: rad, `Dimensionless`).
    pub units: Vec<Unit>,
    /// The covariance (symmetric, `names.len()` square).
    pub matrix: DMatrix<f64>,
    /// The a-posteriori standard deviation of unit weight the matrix was scaled by (1 when the
    /// stated noise explains the residual).
    pub sigma0: f64,
    /// Each identification pose's residual rows in units of the judged noise (the stated noise
    /// times `sigma0`), as a pose the fit did not see would leave them: what an unchanged machine
    /// leaves, by which `kinecal check` and `identify --prior` judge new poses
    /// ([`crate::drift::Reference`]). Written for tracker data where `sigma0` is above 1 (and
    /// kept by an update, whose noise is already the judged one); empty otherwise.
    pub residuals: Vec<Vec<f64>>,
    /// Every other parameter of the model, by name, with why it has no entry (its variance is 0:
    /// it stays as drawn).
    pub held: Vec<(String, Held)>,
}

impl Covariance {
    /// The covariance over `params` (a model's parameter names, in its order): the matrix's
    /// entries where both are identified, 0 elsewhere (held parameters, and names this
    /// covariance does not know).
    pub fn over(&self, params: &[String]) -> DMatrix<f64> {
        let at: Vec<Option<usize>> = params.iter().map(|p| self.names.iter().position(|n| n == p)).collect();
        DMatrix::from_fn(params.len(), params.len(), |i, j| match (at[i], at[j]) {
            (Some(a), Some(b)) => self.matrix[(a, b)],
            _ => 0.0,
        })
    }

    /// The standard deviation of each identified parameter (mm, rad), in [`Self::names`] order.
    pub fn std_devs(&self) -> Vec<f64> {
        (0..self.names.len()).map(|i| self.matrix[(i, i)].max(0.0).sqrt()).collect()
    }
}

fn unit_word(u: Unit) -> &'static str {
    match u {
        Unit::Length => "mm",
        Unit::Angle => "rad",
        Unit::Dimensionless => "1",
    }
}

/// Write `[covariance]`.
pub(super) fn write_covariance(c: &Covariance, out: &mut String) {
    let list = |v: Vec<String>| v.join(", ");
    out.push_str("\n[covariance]  # of the identified parameters: error coordinates of this model about its geometry\n");
    out.push_str("# (frames included); entry (i, j) in units[i]·units[j], always mm and rad whatever [units].\n");
    let _ = writeln!(
        out,
        "sigma0 = {}  # a-posteriori σ of unit weight the matrix was scaled by",
        num(c.sigma0)
    );
    let _ = writeln!(out, "parameters = [{}]", list(c.names.iter().map(|n| quote(n)).collect()));
    let _ = writeln!(out, "units = [{}]", list(c.units.iter().map(|u| quote(unit_word(*u))).collect()));
    out.push_str("matrix = [\n");
    for i in 0..c.matrix.nrows() {
        let row: Vec<String> = (0..c.matrix.ncols()).map(|j| num(c.matrix[(i, j)])).collect();
        let _ = writeln!(out, "    [{}],", row.join(", "));
    }
    out.push_str("]\n");
    if !c.residuals.is_empty() {
        out.push_str("# Each identification pose's residual rows in units of the stated noise times sigma0: what an\n");
        out.push_str("# unchanged machine leaves, by which kinecal check and identify --prior judge new poses.\n");
        out.push_str("residuals = [\n");
        for r in &c.residuals {
            let row: Vec<String> = r.iter().map(|v| format!("{v:.4}")).collect();
            let _ = writeln!(out, "    [{}],", row.join(", "));
        }
        out.push_str("]\n");
    }
    if !c.held.is_empty() {
        out.push_str("[covariance.held]  # the model's other parameters, kept as they are: fixed, redundant, weak or placement\n");
        for (name, why) in &c.held {
            let _ = writeln!(out, "{} = \"{}\"", quote(name), why.word());
        }
    }
}

/// `[covariance]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCovariance {
    sigma0: Spanned<f64>,
    parameters: Spanned<Vec<String>>,
    units: Spanned<Vec<String>>,
    matrix: Spanned<Vec<Vec<f64>>>,
    residuals: Option<Spanned<Vec<Vec<f64>>>>,
    #[serde(default)]
    held: BTreeMap<String, Held>,
}

impl Ctx<'_> {
    /// `[covariance]` read and checked against the model's parameter names.
    pub(super) fn covariance(&self, raw: &Spanned<RawCovariance>, params: &[crate::params::Param]) -> Result<Covariance, IoError> {
        let r = raw.get_ref();
        let names = r.parameters.get_ref().clone();
        let n = names.len();
        for name in &names {
            if !params.iter().any(|p| &p.name == name) {
                return Err(self.at(
                    &r.parameters.span(),
                    format!("covariance.parameters: '{name}' is no parameter of this model"),
                ));
            }
        }
        if let Some(dup) = names.iter().enumerate().find(|(i, a)| names[..*i].contains(a)).map(|(_, a)| a) {
            return Err(self.at(&r.parameters.span(), format!("covariance.parameters: '{dup}' twice")));
        }
        if r.units.get_ref().len() != n {
            return Err(self.at(
                &r.units.span(),
                format!("covariance.units: {} units for {n} parameters", r.units.get_ref().len()),
            ));
        }
        let mut units = Vec::with_capacity(n);
        for (word, name) in r.units.get_ref().iter().zip(&names) {
            let unit = match word.as_str() {
                "mm" => Unit::Length,
                "rad" => Unit::Angle,
                "1" => Unit::Dimensionless,
                other => {
                    return Err(self.at(
                        &r.units.span(),
                        format!("covariance.units: '{other}' for '{name}' (the matrix is in \"mm\", \"rad\" or \"1\")"),
                    ))
                }
            };
            let model = params.iter().find(|p| &p.name == name).map(|p| p.unit);
            if model != Some(unit) {
                return Err(self.at(
                    &r.units.span(),
                    format!("covariance.units: '{word}' for '{name}', which is not that parameter's unit"),
                ));
            }
            units.push(unit);
        }
        let rows = r.matrix.get_ref();
        if rows.len() != n || rows.iter().any(|row| row.len() != n) {
            return Err(self.at(&r.matrix.span(), format!("covariance.matrix: expected {n} rows of {n} values")));
        }
        let matrix = DMatrix::from_fn(n, n, |i, j| rows[i][j]);
        let symmetric = (0..n).all(|i| (0..n).all(|j| matrix[(i, j)] == matrix[(j, i)]));
        if matrix.iter().any(|v| !v.is_finite()) || (0..n).any(|i| matrix[(i, i)] < 0.0) || !symmetric {
            return Err(self.at(
                &r.matrix.span(),
                "covariance.matrix: must be finite and symmetric with variances ≥ 0".into(),
            ));
        }
        let sigma0 = *r.sigma0.get_ref();
        if !(sigma0.is_finite() && sigma0 >= 0.0) {
            return Err(self.at(&r.sigma0.span(), "covariance.sigma0: must be finite and ≥ 0".into()));
        }
        let residuals = match &r.residuals {
            Some(res) => {
                let v = res.get_ref();
                if v.iter().any(|row| row.is_empty() || row.iter().any(|x| !x.is_finite())) {
                    return Err(self.at(
                        &res.span(),
                        "covariance.residuals: each pose's rows must be finite, at least one".into(),
                    ));
                }
                v.clone()
            }
            None => Vec::new(),
        };
        let mut held = Vec::with_capacity(r.held.len());
        for p in params {
            if let Some(why) = r.held.get(&p.name) {
                held.push((p.name.clone(), *why));
            }
        }
        if let Some(name) = r.held.keys().find(|k| !params.iter().any(|p| &p.name == *k)) {
            return Err(self.at(&raw.span(), format!("covariance.held: '{name}' is no parameter of this model")));
        }
        if let Some((name, _)) = held.iter().find(|(h, _)| names.contains(h)) {
            return Err(self.at(&raw.span(), format!("covariance.held: '{name}' is also in covariance.parameters")));
        }
        Ok(Covariance {
            names,
            units,
            matrix,
            sigma0,
            residuals,
            held,
        })
    }
}

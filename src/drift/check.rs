//! [`check()`]: re-measured poses judged against a calibration's prediction.
use super::patterns::{patterns, Pattern, PatternKind};
use super::reference::{quantile, Null, NullRows, Reference};
use super::stacked::Stacked;
use super::{chi2_at_z, chi2_quantile, rate, Prior, DEFAULT_FALSE_ALARM};
use crate::error::CalibError;
use crate::identify::linearize;
use crate::measure::{self, Measurement};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use serde::Serialize;

/// Options of [`check()`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckOptions {
    /// The false-alarm rate of the check (and of each pose's own test): the probability of
    /// "drifted" for a machine as calibrated.
    pub false_alarm: f64,
    /// Seed of the configurations the patterns are found at ([`super::patterns()`]) and of the
    /// simulations that set the thresholds ([`super::rate`], each pose's with a [`Reference`]).
    pub seed: u64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            false_alarm: DEFAULT_FALSE_ALARM,
            seed: 1,
        }
    }
}

/// One pose judged against its prediction.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PoseCheck {
    /// Index of the pose in the data.
    pub index: usize,
    /// Its residual rows.
    pub rows: usize,
    /// `eᵀ·C⁻¹·e` over its rows (χ² with `rows` degrees of freedom when as calibrated).
    pub chi2: f64,
    /// The χ² quantile of its rows at the false-alarm rate; with the prior's [`Reference`], the
    /// quantile of its statistic over rows drawn from the calibration's own where that is higher.
    pub bound: f64,
    /// Position error (mm).
    pub position_mm: f64,
    /// Orientation error (deg), when measured.
    pub orientation_deg: Option<f64>,
    /// The position error the prediction expects (mm, RMS of the 3-D error: the parameters'
    /// covariance at this pose and the noise).
    pub expected_mm: f64,
    /// An instrument's rows: the artifact point whose rows these are, judged together (then
    /// `index` is the point's block, `position_mm` the RMS over its poses of the tool point's
    /// distance from it, `expected_mm` what the prediction expects of that RMS).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub artifact: Option<super::ArtifactRows>,
}

impl PoseCheck {
    /// Whether the pose alone is beyond its bound.
    pub fn beyond(&self) -> bool {
        self.chi2 > self.bound
    }
}

/// One coefficient of a fitted pattern, in the unit shown.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PatternValue {
    /// Its label.
    pub label: String,
    /// The fitted change.
    pub value: f64,
    /// Its standard deviation.
    pub sigma: f64,
    /// `"mm"`, `"deg"`, `"ppm"`.
    pub unit: &'static str,
}

/// A pattern fitted to the new rows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PatternFit {
    /// The pattern's name.
    pub name: String,
    /// Its kind.
    pub kind: PatternKind,
    /// Its fitted coefficients.
    pub values: Vec<PatternValue>,
    /// How much releasing it lowers the statistic, `Δ`.
    pub chi2_drop: f64,
    /// The χ² quantile `Δ` is tested against: of the pattern's size, at the false-alarm rate
    /// divided by the number of patterns tried (an update with a [`Reference`]: the quantile of
    /// `Δ` over rows drawn from it where that is higher).
    pub bound: f64,
    /// The statistic left once it is released.
    pub chi2_after: f64,
    /// The χ² quantile of the rows left, at the false-alarm rate; in [`check()`] with the
    /// prior's [`Reference`], the quantile of what the pattern leaves of rows drawn from the
    /// calibration's own where that is higher.
    pub bound_after: f64,
    /// Patterns the new rows cannot tell from it: each leaves a statistic within the χ² quantile
    /// of one degree of freedom at the false-alarm rate of what this one leaves (both charged
    /// `ln(rows)` per coefficient), best first, at most [`MAX_ALTERNATIVES`]. On a parallel
    /// machine a leg's length, its rail point and its platform joint act through the same
    /// closure, their effects differing only by how the leg's direction varies over the poses.
    pub alternatives: Vec<Alternative>,
    /// Index among [`super::patterns()`].
    #[serde(skip)]
    pub index: usize,
}

/// A pattern that explains the new rows about as well as the one named.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Alternative {
    /// Its name.
    pub name: String,
    /// The statistic left once it is released instead.
    pub chi2_after: f64,
}

/// At most this many [`PatternFit::alternatives`] are kept.
pub const MAX_ALTERNATIVES: usize = 4;

impl PatternFit {
    /// Releasing it lowers the statistic beyond noise.
    pub fn significant(&self) -> bool {
        self.chi2_drop > self.bound
    }

    /// Once released, what is left is noise.
    pub fn explains(&self) -> bool {
        self.chi2_after <= self.bound_after
    }

    /// `joint q2 offset +0.0512 deg (σ 0.0041)`, or `tool position tx +0.1200 ty … mm (σ …)`,
    /// followed by the [`Self::alternatives`] when there are: `; as well: db1z (χ² left 30.2), …`.
    pub fn describe(&self) -> String {
        if self.alternatives.is_empty() {
            return self.describe_alone();
        }
        let others: Vec<String> = self
            .alternatives
            .iter()
            .map(|a| format!("{} (χ² left {:.1})", a.name, a.chi2_after))
            .collect();
        format!(
            "{}; the new poses cannot tell it from: {}",
            self.describe_alone(),
            others.join(", ")
        )
    }

    /// [`Self::describe`] without the alternatives.
    pub fn describe_alone(&self) -> String {
        let v = |x: &PatternValue| format!("{:+.4} {} (σ {:.4})", x.value, x.unit, x.sigma);
        match self.values.as_slice() {
            [one] if one.label == self.name => format!("{} {}", self.name, v(one)),
            all => format!(
                "{}: {}",
                self.name,
                all.iter().map(|x| format!("{} {}", x.label, v(x))).collect::<Vec<_>>().join(", ")
            ),
        }
    }
}

/// The strongest single pattern in [`check()`]'s pattern test: the one whose release lowers the
/// statistic furthest beyond its own bound.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PatternTest {
    /// The pattern's name.
    pub name: String,
    /// How much releasing it lowers the statistic, `Δ` (χ² with as many degrees of freedom as
    /// the pattern has coefficients when as calibrated).
    pub chi2_drop: f64,
    /// Its bound: the χ² value of its size at the deviate [`super::rate::decide`] holds every
    /// statistic to.
    pub bound: f64,
}

impl PatternTest {
    /// Whether `Δ` is beyond its bound.
    pub fn beyond(&self) -> bool {
        self.chi2_drop > self.bound
    }
}

/// The one pose a "drifted" rests on: without it, the other poses agree with the calibration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OnePose {
    /// Index of the pose in the data.
    pub index: usize,
    /// `T` over the other poses' rows.
    pub chi2_without: f64,
    /// Their rows.
    pub rows_without: usize,
    /// Their bound (as [`CheckReport::bound`], for those rows).
    pub bound_without: f64,
}

/// What [`check()`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckReport {
    /// The statistic over all new rows or a pattern's drop is beyond its bound.
    pub drifted: bool,
    /// `T`, χ² with [`Self::rows`] degrees of freedom when as calibrated.
    pub chi2: f64,
    /// Rows of the new measurements.
    pub rows: usize,
    /// The bound of `T`: the χ² value of the rows at the deviate every statistic is held to
    /// ([`super::rate`]: the statistic over all rows and each pattern's drop together raise a
    /// false alarm at the stated rate).
    pub bound: f64,
    /// The pattern whose release lowers `T` furthest beyond its own bound. A drift of one
    /// pattern concentrates in its few coefficients, which this sees where `T` spreads it over
    /// as many degrees of freedom as rows.
    pub pattern_test: Option<PatternTest>,
    /// The false-alarm rate.
    pub false_alarm: f64,
    /// Each pose judged alone.
    pub poses: Vec<PoseCheck>,
    /// The pattern that fits the new rows best, and the number of patterns tried.
    pub pattern: Option<PatternFit>,
    /// Patterns tried.
    pub patterns_tried: usize,
    /// When the rows as a whole are beyond the bound but not without the pose that weighs most
    /// (of three or more), and setting that pose's rows free explains them better than the best
    /// pattern does (each coefficient charged `ln(rows)`): that pose. The verdict is then "still
    /// calibrated", with that pose named to be measured again: a blunder or an error local to one
    /// pose is not a drift of the machine.
    pub one_pose: Option<OnePose>,
}

impl CheckReport {
    /// `still calibrated` or `drifted`, with the statistic.
    ///
    /// When only the pattern test is beyond its bound, it says so:
    /// `drifted: χ² 41.3 over 30 rows (bound 53.7), but joint g2 zero alone lowers it by 19.0,
    /// beyond its bound 15.4; false-alarm rate 1 %`.
    pub fn verdict(&self) -> String {
        let word = if self.drifted { "drifted" } else { "still calibrated" };
        let rate = 100.0 * self.false_alarm;
        if let Some(o) = &self.one_pose {
            let pose = &self.poses[o.index];
            if let Some(a) = &pose.artifact {
                return format!(
                    "{word}: the other artifact points agree (χ² {:.1} over {} rows, bound {:.1} at a false-alarm rate of {rate} %); {} alone disagrees ({:.4} mm RMS off it, χ² {:.1} over {} rows): measure there again",
                    o.chi2_without, o.rows_without, o.bound_without, a.name, pose.position_mm, pose.chi2, pose.rows
                );
            }
            return format!(
                "{word}: the other poses agree (χ² {:.1} over {} rows, bound {:.1} at a false-alarm rate of {rate} %); one pose alone disagrees ({:.4} mm off, χ² {:.1} over {} rows): measure it again",
                o.chi2_without, o.rows_without, o.bound_without, pose.position_mm, pose.chi2, pose.rows
            );
        }
        match &self.pattern_test {
            Some(t) if t.beyond() && self.chi2 <= self.bound => format!(
                "{word}: χ² {:.1} over {} rows (bound {:.1}), but {} alone lowers it by {:.1}, beyond its bound {:.1}; false-alarm rate {rate} %",
                self.chi2, self.rows, self.bound, t.name, t.chi2_drop, t.bound
            ),
            _ => format!(
                "{word}: χ² {:.1} over {} rows, bound {:.1} at a false-alarm rate of {rate} %",
                self.chi2, self.rows, self.bound
            ),
        }
    }
}

/// Judge `data` (re-measured poses, any measurement kind the model's rows take) against the
/// prediction of `prior` (see the [module docs](super)): the statistic over all rows and each
/// pattern's drop ([`CheckReport::pattern_test`]) at one threshold that holds `opts.false_alarm`
/// for them together ([`super::rate`]); each pose alone; and the best pattern.
///
/// Errors: the covariance does not match the model, kinematics failing at a pose.
pub fn check(prior: &Prior, data: &[Measurement], opts: &CheckOptions) -> Result<CheckReport, CalibError> {
    if !(opts.false_alarm > 0.0 && opts.false_alarm < 1.0) {
        return Err(CalibError::InvalidOption(format!(
            "the false-alarm rate must be between 0 and 1 (it is {})",
            opts.false_alarm
        )));
    }
    if data.is_empty() {
        return Err(CalibError::NothingToIdentify("no poses to check".into()));
    }
    let model = prior.model.build();
    prior.check_size(model.n_params())?;
    let l = prior.factor();
    let projected = super::artifact_rows::project(&prior.model, data, &prior.noise)?;
    let lin = match &projected {
        Some(p) => p.lin.clone(),
        None => linearize(&*model, data, &prior.noise)?,
    };
    let rows = lin.residual.len();
    let none = DMatrix::zeros(model.n_params(), 0);
    let stacked = Stacked::new(&lin, &l, &none, &DVector::zeros(l.ncols()));
    let base = stacked
        .solve(None)?
        .ok_or_else(|| CalibError::Numerical("the prior's rows are singular".into()))?;
    let alpha = opts.false_alarm;
    // The new rows' Jacobian times the prior's factor: the rows' predicted covariance I + B·Bᵀ.
    let b = &lin.jacobian * &l;
    let poses = match &projected {
        Some(p) => artifact_checks(&p.points, &lin, &b, &prior.noise, alpha),
        None => pose_checks(prior, &*model, data, &lin, &b, alpha, opts.seed)?,
    };
    // An instrument calibration carries no residuals: its rows are judged as Gaussian.
    let reference_rows = prior.reference.as_ref().filter(|_| projected.is_none());
    let mut all = patterns(&*model, &prior.model.inputs(), opts.seed)?;
    if let Some(p) = &projected {
        all.retain(|pattern| p.sees(&pattern.directions));
    }
    let mut pattern = best_pattern(&stacked, &lin.jacobian, &all, &[], base.cost, rows, alpha)?;
    // What the named pattern leaves judged, as the rows were, by the calibration's own
    // residuals where it has them (held at least at the χ² quantile).
    if let (Some(p), Some(reference)) = (pattern.as_mut(), reference_rows) {
        let null = Null {
            reference,
            layout: &lin.layout(),
            l: &l,
            jacobian: &lin.jacobian,
        };
        if let Some(bound) = null.bound(&all[p.index].directions, None, 1.0 - alpha, rate::NULL_DRAWS, opts.seed) {
            p.bound_after = p.bound_after.max(bound);
        }
    }
    let effects: Vec<DMatrix<f64>> = all.iter().map(|p| &lin.jacobian * &p.directions).collect();
    let layout = lin.layout();
    let reference = reference_rows.map(|r| (&layout[..], r));
    let decision = rate::decide(&b, &lin.residual, &effects, alpha, opts.seed, reference)?;
    let bound = chi2_at_z(rows, decision.z);
    let pattern_test = decision.strongest().and_then(|(i, _)| {
        decision.drops[i].map(|(drop, k)| PatternTest {
            name: all[i].name.clone(),
            chi2_drop: drop,
            bound: chi2_at_z(k, decision.z),
        })
    });
    let mut drifted = decision.deviate(rows) > decision.z;
    let mut one_pose = None;
    if drifted && data.len() >= 3 {
        one_pose = without_worst(&lin, &b, &effects, &poses, alpha, opts.seed, reference_rows)?;
        // One pose's rows set free against the best pattern, each coefficient charged ln(rows)
        // as the patterns are: a drift that a pattern explains stays a drift, even where one
        // pose shows most of it.
        let charge = (rows.max(2) as f64).ln();
        if let (Some(o), Some(p)) = (&one_pose, &pattern) {
            let freed = (rows - o.rows_without) as f64;
            if o.chi2_without + freed * charge >= p.chi2_after + p.values.len() as f64 * charge {
                one_pose = None;
            }
        }
        drifted = one_pose.is_none();
    }
    Ok(CheckReport {
        drifted,
        chi2: base.cost,
        rows,
        bound,
        pattern_test,
        false_alarm: alpha,
        poses,
        pattern,
        patterns_tried: all.len(),
        one_pose,
    })
}

/// The pose whose rows weigh most (the largest χ² of its own), when without it the other rows
/// are within the bound at the same false-alarm rate; `None` when they are still beyond it.
fn without_worst(
    lin: &crate::identify::Linearization,
    b: &DMatrix<f64>,
    effects: &[DMatrix<f64>],
    poses: &[PoseCheck],
    alpha: f64,
    seed: u64,
    reference: Option<&Reference>,
) -> Result<Option<OnePose>, CalibError> {
    let Some(worst) = poses.iter().max_by(|a, b| a.chi2.total_cmp(&b.chi2)) else {
        return Ok(None);
    };
    let start = lin.offsets[worst.index];
    let keep: Vec<usize> = (0..lin.residual.len()).filter(|&r| r < start || r >= start + worst.rows).collect();
    let e = DVector::from_iterator(keep.len(), keep.iter().map(|&r| lin.residual[r]));
    let others: Vec<DMatrix<f64>> = effects.iter().map(|g| g.select_rows(&keep)).collect();
    let layout: Vec<usize> = (0..lin.offsets.len())
        .filter(|&i| i != worst.index)
        .map(|i| lin.pose_rows(i).len())
        .collect();
    let d = rate::decide(&b.select_rows(&keep), &e, &others, alpha, seed, reference.map(|r| (&layout[..], r)))?;
    if d.deviate(keep.len()) > d.z {
        return Ok(None);
    }
    Ok(Some(OnePose {
        index: worst.index,
        chi2_without: d.chi2,
        rows_without: keep.len(),
        bound_without: chi2_at_z(keep.len(), d.z),
    }))
}

/// Block `i` of `lin`: its rows, its predicted covariance `C = I + B·Bᵀ` and `eᵀ·C⁻¹·e`.
fn block_chi2(lin: &crate::identify::Linearization, b: &DMatrix<f64>, i: usize) -> (usize, DMatrix<f64>, f64) {
    let at = lin.pose_rows(i);
    let (start, n) = (at.start, at.len());
    let bb = b.rows(start, n);
    let c = DMatrix::identity(n, n) + bb * bb.transpose();
    let e = lin.residual.rows(start, n).into_owned();
    let chi2 = c.clone().cholesky().map_or(f64::INFINITY, |ch| e.dot(&ch.solve(&e)));
    (n, c, chi2)
}

/// Each artifact point's statistic over its block of `C = I + B·Bᵀ` (its projected rows) and
/// its bound, the χ² quantile of its rows.
fn artifact_checks(
    points: &[super::ArtifactRows],
    lin: &crate::identify::Linearization,
    b: &DMatrix<f64>,
    noise: &measure::Noise,
    alpha: f64,
) -> Vec<PoseCheck> {
    points
        .iter()
        .enumerate()
        .map(|(i, point)| {
            let (n, c, chi2) = block_chi2(lin, b, i);
            // The rows are in units of the position noise: their predicted sum of squares over
            // the point's poses, as mm² per pose.
            let expected = (c.trace() / point.poses.len().max(1) as f64).sqrt() * noise.position;
            PoseCheck {
                index: i,
                rows: n,
                chi2,
                bound: chi2_quantile(n, 1.0 - alpha),
                position_mm: point.rms_mm,
                orientation_deg: None,
                expected_mm: expected,
                artifact: Some(point.clone()),
            }
        })
        .collect()
}

/// Each pose's statistic over its block of `C = I + B·Bᵀ` (`B = A·L`, noise-weighted rows), and
/// its bound: the χ² quantile of its rows, or with the prior's [`Reference`] the quantile of the
/// statistic over rows drawn from it (from `seed`) where that is higher.
fn pose_checks(
    prior: &Prior,
    model: &dyn crate::model::Mechanism,
    data: &[Measurement],
    lin: &crate::identify::Linearization,
    b: &DMatrix<f64>,
    alpha: f64,
    seed: u64,
) -> Result<Vec<PoseCheck>, CalibError> {
    let reached = crate::validate::forward_all(model, data)?;
    let mut out = Vec::with_capacity(data.len());
    for (i, m) in data.iter().enumerate() {
        let (n, c, chi2) = block_chi2(lin, b, i);
        let bb = b.rows(lin.pose_rows(i).start, n);
        let weights = measure::row_weights(&m.obs, &prior.noise);
        let positions = n.min(3).min(weights.len());
        let expected = (0..positions).map(|k| c[(k, k)] / (weights[k] * weights[k])).sum::<f64>().sqrt();
        let (position_mm, orientation) = measure::errors(&m.obs, &reached[i]);
        let null = prior
            .reference
            .as_ref()
            .and_then(|r| NullRows::new(&bb.into_owned(), &[n], Some(r)));
        let bound = match null {
            Some(null) => {
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed.wrapping_add(i as u64));
                let drawn = quantile(rate::NULL_DRAWS, 1.0 - alpha, &mut rng, |rng| null.draw(rng).norm_squared());
                drawn.max(chi2_quantile(n, 1.0 - alpha))
            }
            None => chi2_quantile(n, 1.0 - alpha),
        };
        out.push(PoseCheck {
            index: i,
            rows: n,
            chi2,
            bound,
            position_mm,
            orientation_deg: orientation.map(f64::to_degrees),
            expected_mm: expected,
            artifact: None,
        });
    }
    Ok(out)
}

/// The pattern (not among `skip`) that leaves the least of the statistic `cost` once released,
/// each of its coefficients charged `ln(rows)` (Schwarz's criterion), fitted on `stacked` (new rows' Jacobian `a`), with `rows` new rows (of which
/// the already released patterns' coefficients take `stacked`'s extra columns).
pub(super) fn best_pattern(
    stacked: &Stacked,
    a: &DMatrix<f64>,
    all: &[Pattern],
    skip: &[usize],
    cost: f64,
    rows: usize,
    alpha: f64,
) -> Result<Option<PatternFit>, CalibError> {
    let tried = all.len().max(1) as f64;
    let released = stacked.k.ncols() - stacked.r;
    let mut best: Option<(f64, usize, f64, DVector<f64>)> = None;
    let mut scores: Vec<(f64, usize, f64)> = Vec::new();
    for (i, pat) in all.iter().enumerate() {
        if skip.contains(&i) {
            continue;
        }
        let g = a * &pat.directions;
        if g.norm() <= 1e-12 {
            continue;
        }
        let Some(sol) = stacked.solve(Some(&g))? else { continue };
        let drop = (cost - sol.cost).max(0.0);
        let k = pat.directions.ncols();
        // What is left, each coefficient charged ln(rows) (Schwarz's criterion): a pattern of
        // more coefficients is named only where it explains clearly more.
        let score = -(sol.cost + k as f64 * (rows.max(2) as f64).ln());
        scores.push((score, i, sol.cost));
        if best.as_ref().is_none_or(|b| score > b.0 + 1e-9) {
            let beta = sol.u.rows(sol.u.len() - k, k).into_owned();
            best = Some((score, i, drop, beta));
        }
    }
    let Some((top, i, drop, beta)) = best else {
        return Ok(None);
    };
    let margin = chi2_quantile(1, 1.0 - alpha);
    scores.retain(|&(score, j, _)| j != i && score >= top - margin);
    scores.sort_by(|a, b| b.0.total_cmp(&a.0));
    let alternatives = scores
        .iter()
        .take(MAX_ALTERNATIVES)
        .map(|&(_, j, chi2_after)| Alternative {
            name: all[j].name.clone(),
            chi2_after,
        })
        .collect();
    let pat = &all[i];
    let k = pat.directions.ncols();
    let g = a * &pat.directions;
    let cov = stacked.covariance(Some(&g));
    let n = stacked.k.ncols();
    let values = pat
        .coefficients
        .iter()
        .enumerate()
        .map(|(j, c)| PatternValue {
            label: c.label.clone(),
            value: beta[j] * c.factor,
            sigma: cov
                .as_ref()
                .map_or(f64::NAN, |m| m[(n + j, n + j)].max(0.0).sqrt() * c.factor.abs()),
            unit: c.unit,
        })
        .collect();
    Ok(Some(PatternFit {
        name: pat.name.clone(),
        kind: pat.kind,
        values,
        chi2_drop: drop,
        bound: chi2_quantile(k, 1.0 - alpha / tried),
        chi2_after: cost - drop,
        bound_after: chi2_quantile(rows.saturating_sub(k + released).max(1), 1.0 - alpha),
        alternatives,
        index: i,
    }))
}

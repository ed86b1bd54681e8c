//! The 5-DOF double-driven PUU-2PR(RPRR)S parallel mechanism of the 5-DOF paper
//! (`001_8dc75bc45f73c552.txt`, §2), as a [`ConstraintSystem`].
//!
//! # Equations (written once, generic over the scalar)
//! Platform pose `X = (x, y, z, α, β, γ)`, `R = Rot(x,α)Rot(y,β)Rot(z,γ)` (eq. (2)); actuators
//! `q = (g1, g2, g3, g4, g5)`: the three rail sliders and the two sub-loop actuators (`g4` drives
//! limb 2's sub-closed loop, `g5` limb 3's). Rail `i` is the line `b_i + g_i·w_i`,
//! `w_i = (cos φ_i, sin φ_i, 0)`; actuator offsets `dg_i` add to the commanded values.
//!
//! 1. PUU limb, eq. (1): `|p + R·c1 − b1 − g1·w1| − l1 = 0`.
//! 2. PR(RPRR)S limb 2 reduced to the equivalent PRPS limb, eq. (5): the revolute axis at `B2` is
//!    the rail direction, so `C2 = p + R·c2` satisfies `w2·(C2 − b2) − g2 = 0` (the rod is normal
//!    to the rail) and `|C2 − b2 − g2·w2| − L22 = 0`, with `L22(l2, l3, l4, l5, g4)` the cosine law
//!    of eq. (9).
//! 3. Limb 3 likewise with `(g3, c3, b3, φ3, l6, l7, l8, l9, g5)` (eq. (12)–(13)).
//! 4. The parasitic-motion constraint, from its geometric meaning (Fig. 5): `O_H B1`, `B1 C1` and
//!    `O2 C1` are coplanar, `(R·c1 × (C1 − B1))·w1 = 0` (`O_H B1 = g1·w1` is along the rail; its
//!    length cancels), divided by `|c1|` so that it is in mm like the other rows.
//!
//! Writing the equations from their geometry rather than copying the printed differentials avoids
//! two known misprints: eq. (15) lacks the factor `d` (the triple product is
//! `(2/3)·d·g1·[x sα cγ + (z−h) cβ sγ + x cα sβ sγ]`) and has the opposite sign of the triple
//! product it states, and eq. (12)'s `dφ3` term has the sign opposite to eq. (7)'s (here both
//! limbs share one generic function, so they cannot disagree). Neither affects a model built from
//! the constraints.
//!
//! # Parameters (the 44 of dW, in the paper's order and with its names)
//! `dg1, dc1x, dc1y, dc1z, db1x, db1y, db1z, dl1, dφ1, dg2, dc2x, dc2y, dc2z, db2x, db2y, db2z,
//! dφ2, dl2, dl3, dl4, dl5, dg4, dg3, dc3x, dc3y, dc3z, db3x, db3y, db3z, dφ3, dl6, dl7, dl8,
//! dl9, dg5` (the 35 of dW1, eq. (14)), then the tool offset `dtx, dty, dtz` (eq. (23)) and the
//! base frame `dx0, dy0, dz0, dα0, dβ0, dγ0` (eq. (30)): 35 + 3 + 6 = 44.
//!
//! # Parasitic constraint: physical or the paper's
//! [`Parasitic::Physical`] (the default) evaluates the coplanarity on the *current* geometry
//! (`c1, b1, φ1` with their errors): a real machine's constraint moves with its parts. The paper's
//! model (eq. (16)–(18)) evaluates it error-free on the nominal geometry
//! ([`Parasitic::NominalGeometry`]); then base and tool errors become visible through γ alone,
//! which raises the rank of the identification Jacobian (35 in the paper) by making weakly
//! identifiable combinations that a physical machine does not have.
//!
//! Measured with [`crate::identifiability`] (40 random workspace configurations, full poses weighted by
//! 20 µm / 0.02°, relative rank tolerance 1e-8; asserted in `tests/it/closed.rs`):
//!
//! * paper's model: rank **35** of 44; in the natural order the redundant parameters are
//!   `db1y db2y dl4 dl5 db3y dl8 dl9 dty dy0` (the paper's first finding, columns 6, 15, 20, 21,
//!   28, 33, 34, 37, 40), with [`paper_priority`] exactly the paper's
//!   `db1y db2y dl2 dl3 db3y dl6 dl7 dty dy0`; the three extra directions (`dx0, dz0, dγ0` against
//!   the rail offsets) are seen only through γ: the weakest singular value of the column-scaled
//!   Jacobian drops from 3.4e-4 (physical) to 1.7e-5 of the largest (seed 2024);
//! * physical model: rank **32**; redundant additionally `dx0 dz0 dγ0` (a base translation in
//!   x/z or rotation about z is exactly a shift of the rails and joints `b_i`, `φ_i`).
//!
//! Of the five sub-loop parameters only three combinations act (`L22² = A − B·(g4 + dg4)²`), so
//! two are redundant; keeping `dl2, dl3, dg4` ([`natural_priority`], the default) stays representable for any true geometry while `l2 + l5 ≠ l3`
//! (`det ∂(A,B)/∂(l2,l3) ∝ (l2 + l5)² − l3²`).
//!
//! # Geometry (Table 1 of the paper did not survive)
//! Values chosen for this preset, checked for reachability over the whole workspace (actuator
//! Jacobian condition ≤ 5.4, no sign change of its determinant), and kept here:
//! rails through the base origin at height `h` with `φ = 90°, 45°, 135°`; `b_i = (0, 0, h)`,
//! `h = 100 mm`; `c1 = (0, 2d/3, 0)`, `c2 = (d, −d/3, 0)`, `c3 = (−d, −d/3, 0)`, `d = 150 mm` (the
//! isosceles right triangle of §2.1 with its centroid at `O2`); `l1 = 450 mm`;
//! `(l2, l3, l4, l5) = (l6, l7, l8, l9) = (100, 220, 120, 180) mm`; tool `t = (0, 0, 100) mm`;
//! workspace `x, y ∈ [−50, 50] mm`, `z ∈ [350, 450] mm`, `α, β ∈ [−5°, 5°]` (γ is parasitic);
//! strokes `g1 ∈ [300, 550]`, `g2, g3 ∈ [−20, 160]`, `g4, g5 ∈ [160, 280] mm`. Home pose
//! `(0, 0, 400 mm, 0, 0, 0)`. Branch choices of the closed-form inverse: the PUU slider beyond
//! the foot of the rod (`g1 = d·w1 + √(l1² − |d⊥|²)`), the positive sub-loop actuator root.
use crate::error::KinError;
use crate::model::closed::{v3, ClosedLoop, ConstraintSystem, Scalar, Task, Workspace};
use crate::params::{Param, Unit};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// How the parasitic-motion constraint is evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub enum Parasitic {
    /// On the current (real) geometry — physically consistent (default).
    #[default]
    Physical,
    /// Error-free on the nominal geometry, as the paper's eq. (16)–(20).
    NominalGeometry,
}

/// Nominal geometry of the 5-DOF machine (mm, rad).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Pm5Geometry {
    /// Rail height `h` (`b_i = (0, 0, h)`).
    pub h: f64,
    /// Platform size `d`.
    pub d: f64,
    /// PUU rod length `l1`.
    pub l1: f64,
    /// Sub-loop lengths `(l2, l3, l4, l5)` of limb 2 (and `(l6, l7, l8, l9)` of limb 3).
    pub sub_loop: [f64; 4],
    /// Rail angles `φ1, φ2, φ3`.
    pub phi: [f64; 3],
    /// Tool offset `t`.
    pub tool: [f64; 3],
}

impl Default for Pm5Geometry {
    fn default() -> Self {
        Pm5Geometry {
            h: 100.0,
            d: 150.0,
            l1: 450.0,
            sub_loop: [100.0, 220.0, 120.0, 180.0],
            phi: [PI / 2.0, PI / 4.0, 3.0 * PI / 4.0],
            tool: [0.0, 0.0, 100.0],
        }
    }
}

/// The 5-DOF PUU-2PR(RPRR)S constraint system.
#[derive(Debug, Clone, PartialEq)]
pub struct Pm5 {
    nominal: Vec<f64>,
    reference: Vec<f64>,
    parasitic: Parasitic,
    strokes: [(f64, f64); 5],
    workspace: Workspace,
    home: [f64; 6],
}

/// Number of geometric parameters `θ` of [`Pm5`] (dW1, eq. (14)).
pub const GEOMETRY_PARAMS: usize = 35;

/// The default candidate grid of the machine's platform workspace: the paper samples
/// `N = 304,920` candidate poses; this grid of the five commanded coordinates `(x, y, z, α, β)`
/// has `11·11·21·12·10 = 304,920` points (γ, the parasitic rotation, fixed).
pub const CANDIDATE_GRID: [usize; 6] = [11, 11, 21, 12, 10, 1];

/// Parameter names of dW (44), in the paper's order.
pub const PARAM_NAMES: [&str; 44] = [
    "dg1", "dc1x", "dc1y", "dc1z", "db1x", "db1y", "db1z", "dl1", "dφ1", "dg2", "dc2x", "dc2y", "dc2z", "db2x", "db2y", "db2z", "dφ2",
    "dl2", "dl3", "dl4", "dl5", "dg4", "dg3", "dc3x", "dc3y", "dc3z", "db3x", "db3y", "db3z", "dφ3", "dl6", "dl7", "dl8", "dl9", "dg5",
    "dtx", "dty", "dtz", "dx0", "dy0", "dz0", "dα0", "dβ0", "dγ0",
];

/// The paper's redundant parameters (§3.2, 1-based positions 6, 15, 18, 19, 28, 31, 32, 37, 40).
pub const PAPER_REDUNDANT: [&str; 9] = ["db1y", "db2y", "dl2", "dl3", "db3y", "dl6", "dl7", "dty", "dy0"];

impl Pm5 {
    /// The machine with `geometry` and the parasitic constraint evaluated as `parasitic`.
    pub fn new(geometry: Pm5Geometry, parasitic: Parasitic) -> Self {
        let g = &geometry;
        let d = g.d;
        let [l2, l3, l4, l5] = g.sub_loop;
        #[rustfmt::skip]
        let nominal = vec![
            0.0, 0.0, 2.0 * d / 3.0, 0.0, 0.0, 0.0, g.h, g.l1, g.phi[0],
            0.0, d, -d / 3.0, 0.0, 0.0, 0.0, g.h, g.phi[1], l2, l3, l4, l5, 0.0,
            0.0, -d, -d / 3.0, 0.0, 0.0, 0.0, g.h, g.phi[2], l2, l3, l4, l5, 0.0,
        ];
        let a = 5f64.to_radians();
        Pm5 {
            reference: nominal.clone(),
            nominal,
            parasitic,
            strokes: [(300.0, 550.0), (-20.0, 160.0), (-20.0, 160.0), (160.0, 280.0), (160.0, 280.0)],
            workspace: Workspace {
                min: [-50.0, -50.0, 350.0, -a, -a, 0.0],
                max: [50.0, 50.0, 450.0, a, a, 0.0],
            },
            home: [0.0, 0.0, 400.0, 0.0, 0.0, 0.0],
        }
    }

    /// A machine of arbitrary geometry: the 35 absolute values `θ` in the order of
    /// [`PARAM_NAMES`]`[..35]` (`g1` offset, `c1`, `b1`, `l1`, `φ1`, `g2` offset, `c2`, `b2`, `φ2`,
    /// `l2…l5`, `g4` offset, then limb 3 likewise), e.g. a calibrated geometry. The paper's
    /// parasitic constraint ([`Parasitic::NominalGeometry`]) is evaluated on `θ` until
    /// [`Self::with_reference`] says otherwise; strokes, workspace and home are the defaults until
    /// replaced. Errors: wrong length, a non-finite value.
    pub fn from_parameters(theta: Vec<f64>, parasitic: Parasitic) -> Result<Self, crate::error::CalibError> {
        check_theta(&theta, "geometry")?;
        let mut m = Pm5::new(Pm5Geometry::default(), parasitic);
        m.reference = theta.clone();
        m.nominal = theta;
        Ok(m)
    }

    /// The geometry on which the paper's parasitic constraint is evaluated (35 values, as in
    /// [`Self::from_parameters`]; only `c1`, `b1` and `φ1` are used). Errors: as
    /// [`Self::from_parameters`].
    pub fn with_reference(mut self, reference: Vec<f64>) -> Result<Self, crate::error::CalibError> {
        check_theta(&reference, "parasitic reference geometry")?;
        self.reference = reference;
        Ok(self)
    }

    /// Replace the actuator strokes `(min, max)` of `g1…g5` (mm).
    pub fn with_strokes(mut self, strokes: [(f64, f64); 5]) -> Self {
        self.strokes = strokes;
        self
    }

    /// Replace the prescribed workspace (γ is parasitic: give `min[5] == max[5]`).
    pub fn with_workspace(mut self, workspace: Workspace) -> Self {
        self.workspace = workspace;
        self
    }

    /// Replace the home pose (the forward-kinematics seed).
    pub fn with_home(mut self, home: [f64; 6]) -> Self {
        self.home = home;
        self
    }

    /// The parasitic-constraint mode.
    pub fn parasitic(&self) -> Parasitic {
        self.parasitic
    }

    /// The geometry the paper's parasitic constraint is evaluated on.
    pub fn reference(&self) -> &[f64] {
        &self.reference
    }

    /// The calibratable mechanism: this system with tool and base frame errors (44 parameters).
    pub fn mechanism(parasitic: Parasitic) -> ClosedLoop<Pm5> {
        let g = Pm5Geometry::default();
        let tool = g.tool;
        ClosedLoop::new(Pm5::new(g, parasitic), tool, true)
    }
}

fn check_theta(theta: &[f64], what: &str) -> Result<(), crate::error::CalibError> {
    if theta.len() != GEOMETRY_PARAMS {
        return Err(crate::error::CalibError::InvalidOption(format!(
            "pm5 {what}: {} values, expected {GEOMETRY_PARAMS}",
            theta.len()
        )));
    }
    if theta.iter().any(|v| !v.is_finite()) {
        return Err(crate::error::CalibError::InvalidOption(format!("pm5 {what}: non-finite value")));
    }
    Ok(())
}

/// `L22` of the cosine law, eq. (9).
pub fn sub_loop_length<D: Scalar>(l2: D, l3: D, l4: D, l5: D, g4: D) -> D {
    let a = l2 + l5;
    let sq = a * a + l3 * l3 + a * l3 * (l4 * l4 + l5 * l5 - g4 * g4) / (l4 * l5);
    sq.sqrt()
}

/// Offsets of one double-driven limb's parameters in θ: `g, c(3), b(3), φ, l(4), g_sub`.
const LIMB2: usize = 9;
const LIMB3: usize = 22;

/// The two equations of a PR(RPRR)S limb reduced to PRPS: rod normal to the rail, rod length
/// `L22` from the sub-loop.
fn double_driven<D: Scalar>(p: &v3::V3<D>, r: &v3::M3<D>, g_rail: D, g_sub: D, t: &[D], sub: &[D]) -> [D; 2] {
    // t: [dg, cx, cy, cz, bx, by, bz, φ]; sub: [l2, l3, l4, l5, dg_sub] (two slices of θ, not
    // a copy: this runs in every Newton step of every candidate).
    let c = v3::add(p, &v3::mul(r, &[t[1], t[2], t[3]]));
    let s = v3::sub(&c, &[t[4], t[5], t[6]]);
    let w = v3::planar(t[7]);
    let g = g_rail + t[0];
    let along = v3::dot(&w, &s) - g;
    let rod = v3::sub(&s, &v3::scale(&w, g));
    let l = sub_loop_length(sub[0], sub[1], sub[2], sub[3], g_sub + sub[4]);
    [along, v3::norm(&rod) - l]
}

impl ConstraintSystem for Pm5 {
    fn name(&self) -> &str {
        "pm5"
    }
    fn input_names(&self) -> Vec<String> {
        ["g1", "g2", "g3", "g4", "g5"].iter().map(|s| s.to_string()).collect()
    }
    fn geometry_params(&self) -> Vec<Param> {
        PARAM_NAMES[..35]
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let unit = if matches!(i, 8 | 16 | 29) { Unit::Angle } else { Unit::Length };
                let group = match i {
                    0..=8 => "limb 1 (PUU)",
                    9..=16 => "limb 2",
                    17..=21 => "limb 2 sub-loop",
                    22..=29 => "limb 3",
                    _ => "limb 3 sub-loop",
                };
                Param::new(*n, unit, group)
            })
            .collect()
    }
    fn nominal_geometry(&self) -> Vec<f64> {
        self.nominal.clone()
    }
    fn equations<D: Scalar>(&self, x: &[D; 6], q: &[D], t: &[D]) -> [D; 6] {
        let p = [x[0], x[1], x[2]];
        let r = v3::rot_xyz(x[3], x[4], x[5]);
        // Limb 1 (PUU), eq. (1).
        let c1 = [t[1], t[2], t[3]];
        let b1 = [t[4], t[5], t[6]];
        let w1 = v3::planar(t[8]);
        let rc1 = v3::mul(&r, &c1);
        let big_c1 = v3::add(&p, &rc1);
        let b1_point = v3::add(&b1, &v3::scale(&w1, q[0] + t[0]));
        let rod1 = v3::sub(&big_c1, &b1_point);
        let f0 = v3::norm(&rod1) - t[7];
        // Limbs 2 and 3.
        let [f1, f2] = double_driven(&p, &r, q[1], q[3], &t[LIMB2..LIMB2 + 8], &t[17..22]);
        let [f3, f4] = double_driven(&p, &r, q[2], q[4], &t[LIMB3..LIMB3 + 8], &t[30..35]);
        // Parasitic motion: coplanarity of O_H B1 (along w1), B1 C1 and O2 C1.
        let f5 = match self.parasitic {
            Parasitic::Physical => v3::dot(&v3::cross(&rc1, &rod1), &w1) / v3::norm(&c1),
            Parasitic::NominalGeometry => {
                let n = &self.reference;
                let c = v3::c::<D>;
                let c1n = [c(n[1]), c(n[2]), c(n[3])];
                let b1n = [c(n[4]), c(n[5]), c(n[6])];
                let w1n = v3::planar(c(n[8]));
                let rc1n = v3::mul(&r, &c1n);
                let arm = v3::sub(&v3::add(&p, &rc1n), &b1n);
                v3::dot(&v3::cross(&rc1n, &arm), &w1n) / v3::norm(&c1n)
            }
        };
        [f0, f1, f2, f3, f4, f5]
    }
    /// Each limb from its rail's origin `b_i` along the rail to its slider, then to its platform
    /// joint `C_i`, and the platform triangle `C1 C2 C3`.
    fn skeleton(&self, x: &[f64; 6], q: &[f64], t: &[f64]) -> Vec<Vec<Vector3<f64>>> {
        if q.len() < 3 || t.len() < LIMB3 + 8 {
            return Vec::new();
        }
        let p = Vector3::new(x[0], x[1], x[2]);
        let rot = v3::rot_xyz(x[3], x[4], x[5]);
        let r = |c: [f64; 3]| Vector3::from(v3::mul(&rot, &c));
        // Per limb: offset of (dg, c, b, φ) in θ; limb 1 has its rod length between b and φ.
        let limbs = [(0, 8), (LIMB2, LIMB2 + 7), (LIMB3, LIMB3 + 7)];
        let mut joints = Vec::with_capacity(3);
        let mut lines: Vec<Vec<Vector3<f64>>> = limbs
            .iter()
            .zip(q)
            .map(|(&(o, phi), g)| {
                let b = Vector3::new(t[o + 4], t[o + 5], t[o + 6]);
                let w = Vector3::from(v3::planar(t[phi]));
                let c = p + r([t[o + 1], t[o + 2], t[o + 3]]);
                joints.push(c);
                vec![b, b + w * (g + t[o]), c]
            })
            .collect();
        lines.push(vec![joints[0], joints[1], joints[2], joints[0]]);
        lines
    }
    fn inputs_for_pose(&self, x: &[f64; 6], t: &[f64]) -> Result<Vec<f64>, KinError> {
        let p = [x[0], x[1], x[2]];
        let r = v3::rot_xyz(x[3], x[4], x[5]);
        // PUU: |C1 − b1 − s·w1| = l1.
        let w1 = v3::planar(t[8]);
        let dvec = v3::sub(&v3::add(&p, &v3::mul(&r, &[t[1], t[2], t[3]])), &[t[4], t[5], t[6]]);
        let along = v3::dot(&dvec, &w1);
        let disc = t[7] * t[7] - v3::dot(&dvec, &dvec) + along * along;
        if disc < 0.0 {
            return Err(KinError::Unreachable(format!(
                "PUU limb: platform joint C1 is {:.1} mm from rail 1, farther than the rod length {:.1} mm",
                (v3::dot(&dvec, &dvec) - along * along).max(0.0).sqrt(),
                t[7]
            )));
        }
        let g1 = along + disc.sqrt() - t[0];
        let mut out = vec![g1, 0.0, 0.0, 0.0, 0.0];
        for (k, (off, sub)) in [(LIMB2, 17usize), (LIMB3, 30usize)].iter().enumerate() {
            let tt = &t[*off..*off + 8];
            let ls = &t[*sub..*sub + 5];
            let c = v3::add(&p, &v3::mul(&r, &[tt[1], tt[2], tt[3]]));
            let s = v3::sub(&c, &[tt[4], tt[5], tt[6]]);
            let w = v3::planar(tt[7]);
            let g = v3::dot(&w, &s);
            let rod = v3::norm(&v3::sub(&s, &v3::scale(&w, g)));
            let (l2, l3, l4, l5) = (ls[0], ls[1], ls[2], ls[3]);
            let a = l2 + l5;
            let g_sq = l4 * l4 + l5 * l5 - (rod * rod - a * a - l3 * l3) * l4 * l5 / (a * l3);
            if g_sq <= 0.0 || !g_sq.is_finite() {
                return Err(KinError::Unreachable(format!(
                    "limb {}: rod length {rod:.1} mm is beyond the sub-closed loop's range",
                    k + 2
                )));
            }
            out[1 + k] = g - tt[0];
            out[3 + k] = g_sq.sqrt() - ls[4];
        }
        Ok(out)
    }
    fn task(&self) -> Task {
        Task::PositionAndAxis
    }
    fn home(&self) -> [f64; 6] {
        self.home
    }
    fn strokes(&self) -> Vec<(f64, f64)> {
        self.strokes.to_vec()
    }
    fn workspace(&self) -> Workspace {
        self.workspace.clone()
    }
}

/// Priority order that reproduces the paper's dW′ (§3.2, eq. (34)): within each sub-loop
/// `dl4, dl5, dg4` come before `dl2, dl3`, so `dl2, dl3` (and `dl6, dl7`) are called redundant.
/// kinecal's default is the natural order instead ([`natural_priority`]): keeping `dl2, dl3,
/// dg4` stays representable for any true geometry while `l2 + l5 ≠ l3`, whereas the paper's
/// choice can sit near a fold of the map `(l4, l5) ↦ L22(·)`.
pub fn paper_priority() -> Vec<usize> {
    let mut v: Vec<usize> = (0..44).collect();
    // Sub-loop 2: indices 17..22 = dl2 dl3 dl4 dl5 dg4 → dl4 dl5 dg4 dl2 dl3.
    v[17..22].copy_from_slice(&[19, 20, 21, 17, 18]);
    v[30..35].copy_from_slice(&[32, 33, 34, 30, 31]);
    v
}

/// The paper's order of dW (0…43): with it the sub-loops keep `dl2, dl3, dg4` (`dl6, dl7, dg5`)
/// and drop `dl4, dl5` (`dl8, dl9`), the choice recommended for iterated identification.
pub fn natural_priority() -> Vec<usize> {
    (0..44).collect()
}

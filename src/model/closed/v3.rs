//! Small generic 3-vector / 3×3-matrix algebra on [`Scalar`]s (row-major arrays), used to write constraint equations once for `f64` and dual numbers.
use super::Scalar;

/// A 3-vector.
pub type V3<D> = [D; 3];
/// A 3×3 matrix, rows first.
pub type M3<D> = [[D; 3]; 3];

/// A constant as a scalar.
pub fn c<D: Scalar>(v: f64) -> D {
    D::from(v)
}
/// `a + b`.
pub fn add<D: Scalar>(a: &V3<D>, b: &V3<D>) -> V3<D> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
/// `a − b`.
pub fn sub<D: Scalar>(a: &V3<D>, b: &V3<D>) -> V3<D> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
/// `s·a`.
pub fn scale<D: Scalar>(a: &V3<D>, s: D) -> V3<D> {
    [a[0] * s, a[1] * s, a[2] * s]
}
/// `a·b`.
pub fn dot<D: Scalar>(a: &V3<D>, b: &V3<D>) -> D {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// `a × b`.
pub fn cross<D: Scalar>(a: &V3<D>, b: &V3<D>) -> V3<D> {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
/// `|a|`.
pub fn norm<D: Scalar>(a: &V3<D>) -> D {
    dot(a, a).sqrt()
}
/// `M·a`.
pub fn mul<D: Scalar>(m: &M3<D>, a: &V3<D>) -> V3<D> {
    [dot(&m[0], a), dot(&m[1], a), dot(&m[2], a)]
}
/// `A·B`.
pub fn matmul<D: Scalar>(a: &M3<D>, b: &M3<D>) -> M3<D> {
    let mut out = [[c::<D>(0.0); 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    out
}
/// Column `j` of `M`.
pub fn column<D: Scalar>(m: &M3<D>, j: usize) -> V3<D> {
    [m[0][j], m[1][j], m[2][j]]
}
/// `R = Rot(x,α)·Rot(y,β)·Rot(z,γ)` (X-Y-Z Euler angles, eq. (2) of the 5-DOF paper).
pub fn rot_xyz<D: Scalar>(a: D, b: D, g: D) -> M3<D> {
    let (sa, ca) = a.sin_cos();
    let (sb, cb) = b.sin_cos();
    let (sg, cg) = g.sin_cos();
    [
        [cb * cg, -(cb * sg), sb],
        [ca * sg + sa * sb * cg, ca * cg - sa * sb * sg, -(cb * sa)],
        [sa * sg - ca * sb * cg, sa * cg + ca * sb * sg, ca * cb],
    ]
}
/// `(cos φ, sin φ, 0)`: a rail direction in the base plane.
pub fn planar<D: Scalar>(phi: D) -> V3<D> {
    let (s, co) = phi.sin_cos();
    [co, s, c(0.0)]
}

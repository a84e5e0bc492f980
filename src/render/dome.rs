//! Textured dome lights: an image in one of UsdLuxDomeLight's layouts
//! (`inputs:texture:format`) in the light's frame as radiance per direction, sampled
//! by the image's luminance, and the piecewise-constant distributions that sampling
//! inverts.
//!
//! Sampling is always over a lat-long grid of directions (the light's +Y pole), whose
//! density in solid angle is the grid's piecewise-constant density over (u, v) divided
//! by the lat-long Jacobian 2π² sin θ — exact whatever the image's layout:
//!
//! - a `latlong` image is that grid itself, weighted by its texels' luminance (each
//!   direction's density is proportional to its radiance's luminance);
//! - any other layout gets a grid of about as many cells as the image has texels,
//!   weighted by the luminance the layout shows across each cell (2 × 2 directions per
//!   cell), plus a floor of 1/1000 of the brightest cell so that no direction the image
//!   lights has density 0 (a texel smaller than a cell is still reached). The density
//!   then follows the radiance to within a cell.

use crate::color::luminance;
use crate::render::phase::{sample_sphere, INV_4PI};
use crate::render::texture::read_texture;
use crate::scene::DomeLight;
use glam::{DMat3, DMat4, DVec3};
use std::f64::consts::PI;
use std::path::Path;

/// UsdLuxDomeLight's `inputs:texture:format`: how the image's texels map to the light's
/// local directions. UsdLux fixes only the lat-long orientation (OpenEXR's); the others
/// follow the light-probe conventions of Debevec's `angmap.cal` (Radiance) and HDRShop,
/// oriented so the image's centre looks down +Z like the lat-long image's centre:
///
/// - `LatLong`: OpenEXR's lat-long map: +Y is the top pole, longitude 0 looks down +Z,
///   longitude +π/2 down +X; the left column is longitude +π, the top row latitude +π/2.
/// - `MirroredBall`: a mirror ball seen by an orthographic camera on +Z (up +Y, right
///   +X) filling the image: the centre reflects +Z, the rim −Z; a point at radius r
///   (1 at the rim) reflects the direction at angle 2 asin r from +Z.
/// - `Angular`: the same disk with the angle from +Z linear in the radius (θ = π r).
/// - `CubeMapVerticalCross`: six square faces in a 3 × 4 cross, seen from inside:
///   +Y on top, then +X, +Z, −X across the middle (the centre face looks down +Z with
///   +Y up, so its right is −X), −Y below it, and −Z at the bottom, upside down (its
///   top edge meets −Y's bottom edge).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    LatLong,
    MirroredBall,
    Angular,
    CubeMapVerticalCross,
}

impl Layout {
    /// The layout of a `inputs:texture:format` token: `automatic` reads a plain image
    /// as lat-long (what other renderers do; a file that declared its own layout would
    /// need a format Nimbus does not read).
    pub fn from_token(format: &str) -> Option<Layout> {
        Some(match format {
            "automatic" | "latlong" => Layout::LatLong,
            "mirroredBall" => Layout::MirroredBall,
            "angular" => Layout::Angular,
            "cubeMapVerticalCross" => Layout::CubeMapVerticalCross,
            _ => return None,
        })
    }

    /// The texel (column, row from the top) of a `width` × `height` image that the
    /// unit local direction `l` reads.
    #[inline]
    fn texel(self, l: DVec3, width: usize, height: usize) -> (usize, usize) {
        let pixel = |u: f64, v: f64| {
            (
                ((u * width as f64) as usize).min(width - 1),
                ((v * height as f64) as usize).min(height - 1),
            )
        };
        match self {
            Layout::LatLong => {
                let (u, v) = latlong_uv(l);
                pixel(u, v)
            }
            Layout::MirroredBall | Layout::Angular => {
                // The disk point (a, b) ∈ unit disk, a right, b up.
                let s = (l.x * l.x + l.y * l.y).sqrt();
                let r = match self {
                    // The normal reflecting +Z's viewer into l is the half vector of l
                    // and +Z, whose sine from +Z is the radius: r = sin(θ/2).
                    Layout::MirroredBall => (0.5 * (1.0 - l.z.clamp(-1.0, 1.0))).sqrt(),
                    _ => l.z.clamp(-1.0, 1.0).acos() / PI,
                };
                let (a, b) = if s > 0.0 {
                    (r * l.x / s, r * l.y / s)
                } else {
                    // ±Z: the centre, or (for −Z) any point of the rim.
                    (r, 0.0)
                };
                pixel(0.5 + 0.5 * a, 0.5 - 0.5 * b)
            }
            Layout::CubeMapVerticalCross => {
                let face = width / 3;
                let (col, row, s, t) = cross_face(l);
                let x = ((0.5 * (s + 1.0) * face as f64) as usize).min(face - 1);
                let y = ((0.5 * (1.0 - t) * face as f64) as usize).min(face - 1);
                (col * face + x, row * face + y)
            }
        }
    }

    /// Whether a `width` × `height` image can have this layout.
    fn check_size(self, width: usize, height: usize) -> Result<(), String> {
        match self {
            Layout::CubeMapVerticalCross if width * 4 != height * 3 || width % 3 != 0 => Err(
                format!("is {width}×{height}: a vertical cross is 3N×4N (six N×N faces)"),
            ),
            _ => Ok(()),
        }
    }
}

/// The face of the vertical cross that unit direction `l` falls on: its (column, row)
/// in the cross and the face coordinates (s right, t up) ∈ [−1, 1]².
fn cross_face(l: DVec3) -> (usize, usize, f64, f64) {
    let a = l.abs();
    // (column, row, face centre, right, up) as the cross shows each face.
    let (col, row, c, right, up) = if a.z >= a.x && a.z >= a.y {
        if l.z > 0.0 {
            (1, 1, DVec3::Z, -DVec3::X, DVec3::Y)
        } else {
            (1, 3, -DVec3::Z, -DVec3::X, -DVec3::Y)
        }
    } else if a.x >= a.y {
        if l.x > 0.0 {
            (0, 1, DVec3::X, DVec3::Z, DVec3::Y)
        } else {
            (2, 1, -DVec3::X, -DVec3::Z, DVec3::Y)
        }
    } else if l.y > 0.0 {
        (1, 0, DVec3::Y, -DVec3::X, -DVec3::Z)
    } else {
        (1, 2, -DVec3::Y, -DVec3::X, DVec3::Z)
    };
    let depth = l.dot(c);
    (col, row, l.dot(right) / depth, l.dot(up) / depth)
}

/// (u, v) ∈ [0,1)² of local direction `l` on the lat-long grid.
fn latlong_uv(l: DVec3) -> (f64, f64) {
    let theta = l.y.clamp(-1.0, 1.0).acos();
    let phi = l.x.atan2(l.z);
    let u = 0.5 - phi / (2.0 * PI);
    (u.rem_euclid(1.0), theta / PI)
}

/// The local direction of lat-long grid position (u, v).
fn latlong_direction(u: f64, v: f64) -> DVec3 {
    let theta = PI * v;
    let phi = PI * (1.0 - 2.0 * u);
    let s = theta.sin();
    DVec3::new(s * phi.sin(), theta.cos(), s * phi.cos())
}

/// Cells of the sampling grid of a layout other than lat-long: rows (N, the grid is
/// 2N × N), about as many cells as the image has texels, at most 1024 rows (2 M cells).
fn grid_rows(width: usize, height: usize) -> usize {
    (((width * height) as f64 / 2.0).sqrt().ceil() as usize).clamp(4, 1024)
}

/// A textured dome light: an image in one of [`Layout`]'s layouts, in the light's frame.
pub struct EnvMap {
    pub width: usize,
    pub height: usize,
    pub layout: Layout,
    /// Radiance per texel (texture × the light's emission scale), row-major from the top.
    pub texels: Vec<[f64; 3]>,
    pub to_world: DMat3,
    pub to_local: DMat3,
    /// Sample by the texture's luminance (true) or uniformly over the sphere (false,
    /// a reference for tests).
    pub importance: bool,
    /// ∫ luminance dω, for choosing between environment strategies.
    pub power: f64,
    /// Over the lat-long grid of directions (see the module documentation).
    distribution: Distribution2D,
}

impl EnvMap {
    /// Reads the dome's texture `file` (any size; its layout from
    /// `inputs:texture:format`) and scales it by the light's emission `scale`.
    pub(super) fn load(light: &DomeLight, file: &str, scale: [f64; 3]) -> Result<EnvMap, String> {
        let Some(layout) = Layout::from_token(&light.texture_format) else {
            return Err(format!(
                "inputs:texture:format `{}` is not a UsdLuxDomeLight format Nimbus reads for {file} (automatic, latlong, mirroredBall, angular, cubeMapVerticalCross)",
                light.texture_format
            ));
        };
        if openusd::ar::is_package_relative_path(file) {
            return Err(format!(
                "dome texture {file}: textures inside .usdz packages are not supported"
            ));
        }
        let (width, height, texels) =
            read_texture(Path::new(file)).map_err(|e| format!("dome texture {file}: {e}"))?;
        layout.check_size(width, height).map_err(|e| {
            format!(
                "dome texture {file} {e} (inputs:texture:format `{}`)",
                light.texture_format
            )
        })?;
        let texels = texels
            .into_iter()
            .map(|t| [0, 1, 2].map(|c| scale[c] * t[c]))
            .collect();
        Ok(EnvMap::with_layout(
            layout,
            width,
            height,
            texels,
            light.light_to_world,
        ))
    }

    /// A lat-long map of radiance `texels` (row-major from the top row) oriented by
    /// `light_to_world`.
    pub fn new(width: usize, height: usize, texels: Vec<[f64; 3]>, light_to_world: DMat4) -> Self {
        Self::with_layout(Layout::LatLong, width, height, texels, light_to_world)
    }

    /// A map of radiance `texels` in `layout` (whose size it must fit).
    pub fn with_layout(
        layout: Layout,
        width: usize,
        height: usize,
        texels: Vec<[f64; 3]>,
        light_to_world: DMat4,
    ) -> Self {
        assert_eq!(texels.len(), width * height, "texel count");
        assert!(layout.check_size(width, height).is_ok(), "image size");
        // The dome's orientation: its transform's rotation (columns normalized, so a
        // scale does not distort directions).
        let m = DMat3::from_mat4(light_to_world);
        let to_world = DMat3::from_cols(
            m.x_axis.normalize_or(DVec3::X),
            m.y_axis.normalize_or(DVec3::Y),
            m.z_axis.normalize_or(DVec3::Z),
        );
        let to_local = to_world.inverse();
        let mut map = EnvMap {
            width,
            height,
            layout,
            texels,
            to_world,
            to_local,
            importance: true,
            power: 0.0,
            distribution: Distribution2D::new(&[0.0], 1, 1),
        };
        let (gw, gh, func, power) = match layout {
            Layout::LatLong => {
                let mut func = vec![0.0; width * height];
                for y in 0..height {
                    let sin_t = (PI * (y as f64 + 0.5) / height as f64).sin();
                    for x in 0..width {
                        func[y * width + x] = luminance(map.texels[y * width + x]).max(0.0) * sin_t;
                    }
                }
                (width, height, func, None)
            }
            _ => {
                let gh = grid_rows(width, height);
                let gw = 2 * gh;
                // Mean luminance over 2 × 2 directions per cell.
                let mut mean = vec![0.0; gw * gh];
                for y in 0..gh {
                    for x in 0..gw {
                        let mut s = 0.0;
                        for (i, j) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                            let d = latlong_direction(
                                (x as f64 + i) / gw as f64,
                                (y as f64 + j) / gh as f64,
                            );
                            s += luminance(map.local_radiance(d)).max(0.0);
                        }
                        mean[y * gw + x] = 0.25 * s;
                    }
                }
                let floor = 1e-3 * mean.iter().cloned().fold(0.0, f64::max);
                let mut func = vec![0.0; gw * gh];
                let mut integral = 0.0;
                for y in 0..gh {
                    let sin_t = (PI * (y as f64 + 0.5) / gh as f64).sin();
                    for x in 0..gw {
                        integral += mean[y * gw + x] * sin_t;
                        func[y * gw + x] = (mean[y * gw + x] + floor) * sin_t;
                    }
                }
                (
                    gw,
                    gh,
                    func,
                    Some(integral / (gw * gh) as f64 * 2.0 * PI * PI),
                )
            }
        };
        map.distribution = Distribution2D::new(&func, gw, gh);
        // ∫ lum dω = ∫∫ lum sinθ · 2π² du dv.
        map.power = power.unwrap_or(map.distribution.integral * 2.0 * PI * PI);
        map
    }

    /// The radiance of every direction, when the image has one colour (Blender writes
    /// a world colour as a 1 × 1 image): such a map is the constant dome of that
    /// colour, and renders as one.
    pub fn constant(&self) -> Option<[f64; 3]> {
        let first = self.texels[0];
        self.texels.iter().all(|t| *t == first).then_some(first)
    }

    /// Radiance from unit local direction `l` (nearest texel).
    #[inline]
    fn local_radiance(&self, l: DVec3) -> [f64; 3] {
        let (x, y) = self.layout.texel(l, self.width, self.height);
        self.texels[y * self.width + x]
    }

    /// Radiance arriving from world direction `w` (nearest texel).
    #[inline]
    pub fn radiance(&self, w: DVec3) -> [f64; 3] {
        self.local_radiance(self.to_local * w)
    }

    /// Density per steradian of [`EnvMap::sample`].
    pub fn pdf(&self, w: DVec3) -> f64 {
        if !self.importance {
            return INV_4PI;
        }
        let (u, v) = latlong_uv(self.to_local * w);
        let sin_t = (PI * v).sin();
        if sin_t <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(u, v) / (2.0 * PI * PI * sin_t)
    }

    /// A world direction, by the sampling grid's density (or uniform).
    pub fn sample(&self, u1: f64, u2: f64) -> DVec3 {
        if !self.importance {
            return sample_sphere(u1, u2);
        }
        let (u, v) = self.distribution.sample(u1, u2);
        (self.to_world * latlong_direction(u, v)).normalize()
    }
}

/// A piecewise-constant density on [0,1] with `n` equal pieces.
struct Distribution1D {
    func: Vec<f64>,
    /// cdf[i] = ∫₀^{i/n}, normalized; n + 1 entries.
    cdf: Vec<f64>,
    /// ∫₀¹ func.
    integral: f64,
}

impl Distribution1D {
    fn new(func: &[f64]) -> Self {
        let n = func.len();
        let mut cdf = vec![0.0; n + 1];
        for i in 0..n {
            cdf[i + 1] = cdf[i] + func[i] / n as f64;
        }
        let integral = cdf[n];
        for (i, c) in cdf.iter_mut().enumerate() {
            *c = if integral > 0.0 {
                *c / integral
            } else {
                i as f64 / n as f64
            };
        }
        Distribution1D {
            func: func.to_vec(),
            cdf,
            integral,
        }
    }

    /// Density of `x` (∈ [0,1)) relative to the unit interval.
    fn pdf(&self, x: f64) -> f64 {
        let n = self.func.len();
        let i = ((x * n as f64) as usize).min(n - 1);
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }

    /// Inverts the cdf at `u`: a position in [0,1).
    fn sample(&self, u: f64) -> f64 {
        let n = self.func.len();
        // Last i with cdf[i] <= u.
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .saturating_sub(1)
            .min(n - 1);
        let span = self.cdf[i + 1] - self.cdf[i];
        let t = if span > 0.0 {
            (u - self.cdf[i]) / span
        } else {
            0.5
        };
        ((i as f64 + t.clamp(0.0, 1.0)) / n as f64).min(1.0 - f64::EPSILON)
    }
}

/// A piecewise-constant density on [0,1]²: rows by their marginal, then a column in
/// the row.
struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
    integral: f64,
}

impl Distribution2D {
    fn new(func: &[f64], width: usize, height: usize) -> Self {
        let rows: Vec<_> = (0..height)
            .map(|y| Distribution1D::new(&func[y * width..(y + 1) * width]))
            .collect();
        let marginal = Distribution1D::new(&rows.iter().map(|r| r.integral).collect::<Vec<_>>());
        let integral = marginal.integral;
        Distribution2D {
            rows,
            marginal,
            integral,
        }
    }

    fn sample(&self, u1: f64, u2: f64) -> (f64, f64) {
        let v = self.marginal.sample(u1);
        let row = ((v * self.rows.len() as f64) as usize).min(self.rows.len() - 1);
        (self.rows[row].sample(u2), v)
    }

    fn pdf(&self, u: f64, v: f64) -> f64 {
        let row = ((v * self.rows.len() as f64) as usize).min(self.rows.len() - 1);
        self.marginal.pdf(v) * self.rows[row].pdf(u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lat-long convention UsdLux adopts from OpenEXR, at its named points.
    #[test]
    fn latlong_axes() {
        let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-12;
        assert!(close(latlong_direction(0.5, 0.5), DVec3::Z)); // lat 0, lon 0
        assert!(close(latlong_direction(0.25, 0.5), DVec3::X)); // lon +π/2
        assert!(close(latlong_direction(0.75, 0.5), -DVec3::X));
        assert!(close(latlong_direction(0.0, 0.5), -DVec3::Z)); // lon +π (left edge)
        assert!(close(latlong_direction(0.3, 0.0), DVec3::Y)); // top row: +Y pole
        for (u, v) in [(0.1, 0.2), (0.6, 0.7), (0.9, 0.45)] {
            let (u2, v2) = latlong_uv(latlong_direction(u, v));
            assert!((u - u2).abs() < 1e-12 && (v - v2).abs() < 1e-12);
        }
    }

    /// ∫ pdf dω = 1 for the importance density (midpoint quadrature over θ, φ).
    #[test]
    fn envmap_pdf_integrates_to_one() {
        let (w, h) = (16, 8);
        let texels = (0..w * h)
            .map(|i| [(i % 7) as f64, 0.5 * (i % 3) as f64, 0.1])
            .collect();
        let map = EnvMap::new(w, h, texels, DMat4::from_rotation_y(0.7));
        let n = 400;
        let mut s = 0.0;
        for i in 0..n {
            for j in 0..2 * n {
                let theta = PI * (i as f64 + 0.5) / n as f64;
                let phi = 2.0 * PI * (j as f64 + 0.5) / (2 * n) as f64;
                let d = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                s += map.pdf(d) * theta.sin() * (PI / n as f64) * (PI / n as f64);
            }
        }
        assert!((s - 1.0).abs() < 1e-3, "∫pdf = {s}");
    }

    /// Each layout's convention at its named points: the texel a direction reads.
    #[test]
    fn layouts_put_named_directions_where_their_conventions_do() {
        let texel = |layout: Layout, d: DVec3, w, h| layout.texel(d.normalize(), w, h);
        // Mirrored ball and angular map, 100 × 100: the centre is +Z, up +Y, right +X,
        // the rim −Z; +X is at radius sin 45° (ball) or 1/2 (angular).
        for layout in [Layout::MirroredBall, Layout::Angular] {
            assert_eq!(texel(layout, DVec3::Z, 100, 100), (50, 50));
            assert_eq!(texel(layout, -DVec3::Z, 100, 100), (99, 50));
            let up = texel(layout, DVec3::Y, 100, 100);
            assert!(up.0 == 50 && up.1 < 50, "{layout:?} +Y at {up:?}");
        }
        assert_eq!(texel(Layout::MirroredBall, DVec3::X, 100, 100), (85, 50));
        assert_eq!(texel(Layout::Angular, DVec3::X, 100, 100), (75, 50));
        assert_eq!(texel(Layout::Angular, -DVec3::Y, 100, 100), (50, 75));
        // 45° from +Z towards +X: ball radius sin 22.5° = 0.383, angular 1/4.
        let d = DVec3::new(1.0, 0.0, 1.0);
        assert_eq!(texel(Layout::MirroredBall, d, 100, 100), (69, 50));
        assert_eq!(texel(Layout::Angular, d, 100, 100), (62, 50));
        // Vertical cross of 4 × 4 faces (12 × 16): face centres, and the upside-down back.
        let cross = |d: DVec3| texel(Layout::CubeMapVerticalCross, d, 12, 16);
        assert_eq!(cross(DVec3::Z), (6, 6));
        assert_eq!(cross(DVec3::Y), (6, 2));
        assert_eq!(cross(DVec3::X), (2, 6));
        assert_eq!(cross(-DVec3::X), (10, 6));
        assert_eq!(cross(-DVec3::Y), (6, 10));
        assert_eq!(cross(-DVec3::Z), (6, 14));
        // Neighbouring faces meet where the cross shows them meeting: just left of the
        // front's left edge is the +X face's right column, and so on.
        let e = 1e-3;
        assert_eq!(cross(DVec3::new(1.0 - e, 0.1, 1.0)), (4, 5)); // front, left column
        assert_eq!(cross(DVec3::new(1.0, 0.1, 1.0 - e)), (3, 5)); // +X, right column
        assert_eq!(cross(DVec3::new(0.1, 1.0 - e, 1.0)), (5, 4)); // front, top row
        assert_eq!(cross(DVec3::new(0.1, 1.0, 1.0 - e)), (5, 3)); // +Y, bottom row
        assert_eq!(cross(DVec3::new(0.1, -1.0, -1.0 + e)), (5, 11)); // −Y, bottom row
        assert_eq!(cross(DVec3::new(0.1, -1.0 + e, -1.0)), (5, 12)); // −Z, top row
        assert!(Layout::CubeMapVerticalCross.check_size(12, 15).is_err());
        assert!(Layout::CubeMapVerticalCross.check_size(13, 16).is_err());
    }

    /// A test texture of `w` × `h`: a smooth pattern, a black band, and one bright texel.
    fn pattern(w: usize, h: usize) -> Vec<[f64; 3]> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if y == h / 3 {
                    [0.0; 3]
                } else if (x, y) == (w / 4, 2 * h / 3) {
                    [400.0, 300.0, 200.0]
                } else {
                    [1.0 + (x % 5) as f64, 0.5 + 0.25 * (y % 3) as f64, 0.2]
                }
            })
            .collect()
    }

    /// Midpoint quadrature over the lat-long grid of directions in the map's frame, with
    /// `rows` × `cols` points: Σ f(world direction) · 2π² sin θ du dv.
    fn quadrature(map: &EnvMap, rows: usize, cols: usize, f: impl Fn(DVec3) -> f64) -> f64 {
        let mut s = 0.0;
        for y in 0..rows {
            let v = (y as f64 + 0.5) / rows as f64;
            let jac = 2.0 * PI * PI * (PI * v).sin() / (rows * cols) as f64;
            for x in 0..cols {
                let u = (x as f64 + 0.5) / cols as f64;
                s += f(map.to_world * latlong_direction(u, v)) * jac;
            }
        }
        s
    }

    /// For every layout, the sampling density is exact: ∫ pdf dω = 1 (quadrature on a
    /// refinement of the sampling grid, where pdf · 2π² sin θ is piecewise constant: to
    /// 1e-9), and the estimator mean(lum L(ω) / pdf(ω)) over 200,000 directions drawn by
    /// `sample` (PCG32, seed 7) equals ∫ lum L dω by quadrature — within 5 standard errors
    /// of the mean plus the quadrature's own error, bounded by the difference between
    /// 600- and 1,200-row quadratures. A pdf missing its layout's Jacobian, or a pdf of 0
    /// where the image is lit, moves the estimate by far more.
    #[test]
    fn every_layout_samples_its_radiance_exactly() {
        use rand::{Rng, SeedableRng};
        let to_world = DMat4::from_rotation_y(0.7) * DMat4::from_rotation_x(-0.3);
        for (layout, w, h) in [
            (Layout::LatLong, 16, 8),
            (Layout::LatLong, 7, 5),
            (Layout::MirroredBall, 24, 24),
            (Layout::Angular, 20, 20),
            (Layout::CubeMapVerticalCross, 12, 16),
        ] {
            let map = EnvMap::with_layout(layout, w, h, pattern(w, h), to_world);
            let (gh, gw) = (
                map.distribution.rows.len(),
                map.distribution.rows[0].func.len(),
            );
            let total = quadrature(&map, 6 * gh, 6 * gw, |d| map.pdf(d));
            assert!(
                (total - 1.0).abs() < 1e-9,
                "{layout:?} {w}×{h}: ∫pdf = {total}"
            );

            let lum = |d: DVec3| luminance(map.radiance(d));
            let (q1, q2) = (
                quadrature(&map, 600, 1200, lum),
                quadrature(&map, 1200, 2400, lum),
            );
            let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
            let n = 200_000;
            let (mut sum, mut sum2) = (0.0, 0.0);
            for _ in 0..n {
                let d = map.sample(rng.gen(), rng.gen());
                let pdf = map.pdf(d);
                assert!(pdf > 0.0, "{layout:?}: sampled a direction of density 0");
                let f = lum(d) / pdf;
                sum += f;
                sum2 += f * f;
            }
            let mean = sum / n as f64;
            let se = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
            let tol = 5.0 * se + (q2 - q1).abs();
            eprintln!("{layout:?} {w}×{h}: ∫pdf − 1 = {:.1e}, estimate {mean:.5} quadrature {q2:.5} ± {tol:.5}", total - 1.0);
            assert!(
                (mean - q2).abs() < tol,
                "{layout:?} {w}×{h}: estimate {mean} vs quadrature {q2} (±{tol}; se {se})"
            );
        }
    }

    /// One colour everywhere is a constant dome; anything else is a map.
    #[test]
    fn one_colour_images_are_constant() {
        let m = DMat4::IDENTITY;
        let one = EnvMap::new(1, 1, vec![[0.5, 0.25, 2.0]], m);
        assert_eq!(one.constant(), Some([0.5, 0.25, 2.0]));
        assert_eq!(
            EnvMap::new(2, 1, vec![[1.0; 3]; 2], m).constant(),
            Some([1.0; 3])
        );
        assert_eq!(
            EnvMap::new(2, 1, vec![[1.0; 3], [1.0, 1.0, 0.5]], m).constant(),
            None
        );
    }
}

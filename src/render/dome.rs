//! Textured dome lights: a lat-long image in the light's frame as radiance per direction,
//! sampled by the image's luminance (with the Jacobian of the mapping), and the
//! piecewise-constant distributions that sampling inverts.

use crate::color::luminance;
use crate::render::phase::{sample_sphere, INV_4PI};
use crate::scene::DomeLight;
use glam::{DMat3, DMat4, DVec3};
use std::f64::consts::PI;
use std::path::Path;

/// A textured dome light: a lat-long image (OpenEXR's convention, which UsdLux adopts:
/// +Y is the top pole, longitude 0 looks down +Z, longitude +π/2 down +X; the image's
/// left column is longitude +π and its top row latitude +π/2) in the light's frame.
pub struct EnvMap {
    pub width: usize,
    pub height: usize,
    /// Radiance per texel (texture × the light's emission scale), row-major from the top.
    pub texels: Vec<[f64; 3]>,
    pub to_world: DMat3,
    pub to_local: DMat3,
    /// Sample by the texture's luminance (true) or uniformly over the sphere (false,
    /// a reference for tests).
    pub importance: bool,
    /// ∫ luminance dω, for choosing between environment strategies.
    pub power: f64,
    distribution: Distribution2D,
}

impl EnvMap {
    pub(super) fn load(light: &DomeLight, file: &str, scale: [f64; 3]) -> Result<EnvMap, String> {
        let err = |message: String| message;
        match light.texture_format.as_str() {
            "automatic" | "latlong" => {}
            other => {
                return Err(err(format!(
                    "inputs:texture:format `{other}` is not supported for {file} (Nimbus reads lat-long textures: `latlong` or `automatic`)"
                )))
            }
        }
        if openusd::ar::is_package_relative_path(file) {
            return Err(err(format!(
                "dome texture {file}: textures inside .usdz packages are not supported"
            )));
        }
        let (width, height, texels) =
            read_rgb_exr(Path::new(file)).map_err(|e| err(format!("dome texture {file}: {e}")))?;
        if light.texture_format == "automatic" && width != 2 * height {
            return Err(err(format!(
                "dome texture {file} is {width}×{height}: inputs:texture:format `automatic` reads lat-long images (2N×N) only; set it to `latlong` to use this image"
            )));
        }
        let texels = texels
            .into_iter()
            .map(|t| [0, 1, 2].map(|c| scale[c] * t[c]))
            .collect();
        Ok(EnvMap::new(width, height, texels, light.light_to_world))
    }

    /// A map of radiance `texels` (row-major from the top row) oriented by `light_to_world`.
    pub fn new(width: usize, height: usize, texels: Vec<[f64; 3]>, light_to_world: DMat4) -> Self {
        assert_eq!(texels.len(), width * height, "texel count");
        // The dome's orientation: its transform's rotation (columns normalized, so a
        // scale does not distort directions).
        let m = DMat3::from_mat4(light_to_world);
        let to_world = DMat3::from_cols(
            m.x_axis.normalize_or(DVec3::X),
            m.y_axis.normalize_or(DVec3::Y),
            m.z_axis.normalize_or(DVec3::Z),
        );
        let to_local = to_world.inverse();
        let mut func = vec![0.0; width * height];
        for y in 0..height {
            let sin_t = (PI * (y as f64 + 0.5) / height as f64).sin();
            for x in 0..width {
                func[y * width + x] = luminance(texels[y * width + x]).max(0.0) * sin_t;
            }
        }
        let distribution = Distribution2D::new(&func, width, height);
        // ∫ lum dω = ∫∫ lum sinθ · 2π² du dv.
        let power = distribution.integral * 2.0 * PI * PI;
        EnvMap {
            width,
            height,
            texels,
            to_world,
            to_local,
            importance: true,
            power,
            distribution,
        }
    }

    /// (u, v) ∈ [0,1)² of local direction `l`.
    fn uv(l: DVec3) -> (f64, f64) {
        let theta = l.y.clamp(-1.0, 1.0).acos();
        let phi = l.x.atan2(l.z);
        let u = 0.5 - phi / (2.0 * PI);
        (u.rem_euclid(1.0), theta / PI)
    }

    fn direction(u: f64, v: f64) -> DVec3 {
        let theta = PI * v;
        let phi = PI * (1.0 - 2.0 * u);
        let s = theta.sin();
        DVec3::new(s * phi.sin(), theta.cos(), s * phi.cos())
    }

    fn texel_index(&self, u: f64, v: f64) -> usize {
        let x = ((u * self.width as f64) as usize).min(self.width - 1);
        let y = ((v * self.height as f64) as usize).min(self.height - 1);
        y * self.width + x
    }

    /// Radiance arriving from world direction `w` (nearest texel).
    #[inline]
    pub fn radiance(&self, w: DVec3) -> [f64; 3] {
        let (u, v) = Self::uv(self.to_local * w);
        self.texels[self.texel_index(u, v)]
    }

    /// Density per steradian of [`EnvMap::sample`].
    pub fn pdf(&self, w: DVec3) -> f64 {
        if !self.importance {
            return INV_4PI;
        }
        let (u, v) = Self::uv(self.to_local * w);
        let sin_t = (PI * v).sin();
        if sin_t <= 0.0 {
            return 0.0;
        }
        self.distribution.pdf(u, v) / (2.0 * PI * PI * sin_t)
    }

    /// A world direction, by the texture's luminance × sin θ (or uniform).
    pub fn sample(&self, u1: f64, u2: f64) -> DVec3 {
        if !self.importance {
            return sample_sphere(u1, u2);
        }
        let (u, v) = self.distribution.sample(u1, u2);
        (self.to_world * Self::direction(u, v)).normalize()
    }
}

/// Reads an EXR's R, G, B (first valid layer, largest level) as row-major rows from the
/// top of the data window.
fn read_rgb_exr(path: &Path) -> Result<(usize, usize, Vec<[f64; 3]>), String> {
    use exr::prelude::*;
    if !path.is_file() {
        return Err("file not found".into());
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |res: Vec2<usize>, _: &RgbaChannels| (res.0, vec![[0f64; 3]; res.0 * res.1]),
        |px: &mut (usize, Vec<[f64; 3]>), pos: Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = px.0;
            px.1[pos.1 * w + pos.0] = [r as f64, g as f64, b as f64];
        },
    )
    .map_err(|e| format!("cannot read as an RGB(A) OpenEXR image: {e}"))?;
    let size = image.layer_data.size;
    let (w, h) = (size.0, size.1);
    if w == 0 || h == 0 {
        return Err("empty image".into());
    }
    let texels = image.layer_data.channel_data.pixels.1;
    if texels.iter().flatten().any(|v| !v.is_finite()) {
        return Err("contains NaN or infinite values".into());
    }
    Ok((w, h, texels))
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
        assert!(close(EnvMap::direction(0.5, 0.5), DVec3::Z)); // lat 0, lon 0
        assert!(close(EnvMap::direction(0.25, 0.5), DVec3::X)); // lon +π/2
        assert!(close(EnvMap::direction(0.75, 0.5), -DVec3::X));
        assert!(close(EnvMap::direction(0.0, 0.5), -DVec3::Z)); // lon +π (left edge)
        assert!(close(EnvMap::direction(0.3, 0.0), DVec3::Y)); // top row: +Y pole
        for (u, v) in [(0.1, 0.2), (0.6, 0.7), (0.9, 0.45)] {
            let (u2, v2) = EnvMap::uv(EnvMap::direction(u, v));
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
}

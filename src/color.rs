//! Colour: the RGB triple every coefficient and radiance is, and UsdLux's colour rules
//! (emission scale, the blackbody table of `colorTemperature`). At the bottom of the
//! module tree: lights, emission and the film all use it, and it uses nothing of theirs.

/// RGB coefficients, one per channel.
pub type Spectrum = [f32; 3];

/// `intensity · 2^exposure · color`.
pub fn emission_scale(intensity: f64, exposure: f64, color: [f64; 3]) -> [f64; 3] {
    color.map(|c| c * intensity * exposure.exp2())
}

/// Pixar's blackbody table (UsdLux, `blackbody.cpp`): linear Rec. 709 colours of
/// 1000 K … 10000 K in 500 K steps, each scaled to a maximum channel of 1, with the
/// end knots repeated for the Catmull-Rom spline.
const BLACKBODY_KNOTS: [[f64; 3]; 22] = [
    [1.000000, 0.027490, 0.000000],
    [1.000000, 0.027490, 0.000000], // 1000 K
    [1.000000, 0.149664, 0.000000],
    [1.000000, 0.256644, 0.008095], // 2000 K
    [1.000000, 0.372033, 0.067450],
    [1.000000, 0.476725, 0.153601], // 3000 K
    [1.000000, 0.570376, 0.259196],
    [1.000000, 0.653480, 0.377155], // 4000 K
    [1.000000, 0.726878, 0.501606],
    [1.000000, 0.791543, 0.628050], // 5000 K
    [1.000000, 0.848462, 0.753228],
    [1.000000, 0.898581, 0.874905], // 6000 K
    [1.000000, 0.942771, 0.991642],
    [0.906947, 0.890456, 1.000000], // 7000 K
    [0.828247, 0.841838, 1.000000],
    [0.765791, 0.801896, 1.000000], // 8000 K
    [0.715255, 0.768579, 1.000000],
    [0.673683, 0.740423, 1.000000], // 9000 K
    [0.638992, 0.716359, 1.000000],
    [0.609681, 0.695588, 1.000000], // 10000 K
    [0.609681, 0.695588, 1.000000],
    [0.609681, 0.695588, 1.000000],
];

/// The RGB colour UsdLux gives a colour temperature (as pxr's
/// `UsdLuxBlackbodyTemperatureAsRgb`): a Catmull-Rom spline through
/// [`BLACKBODY_KNOTS`] over [1000, 10000] K (clamped), scaled to Rec. 709 luminance 1,
/// negative lobes clamped to 0.
pub fn usd_blackbody_rgb(kelvin: f64) -> [f64; 3] {
    let u = ((kelvin - 1000.0) / 9000.0).clamp(0.0, 1.0);
    let segments = BLACKBODY_KNOTS.len() - 4;
    let x = u * segments as f64;
    let seg = (x.floor() as usize).min(segments);
    let t = x - seg as f64;
    let k = &BLACKBODY_KNOTS[seg..seg + 4];
    let rgb = [0, 1, 2].map(|c| {
        let (k0, k1, k2, k3) = (k[0][c], k[1][c], k[2][c], k[3][c]);
        let a = 0.5 * (-k0 + 3.0 * k1 - 3.0 * k2 + k3);
        let b = 0.5 * (2.0 * k0 - 5.0 * k1 + 4.0 * k2 - k3);
        let cc = 0.5 * (-k0 + k2);
        ((a * t + b) * t + cc) * t + k1
    });
    let y = luminance(rgb);
    rgb.map(|v| (v / y).max(0.0))
}

/// Rec. 709 luminance of a linear RGB colour.
pub fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The sRGB transfer function inverted (IEC 61966-2-1): an sRGB-encoded value in
/// [0, 1] (what 8-bit PNG and JPEG files hold) to linear.
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

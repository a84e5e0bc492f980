//! Denoising with Open Image Denoise 2.x (OIDN): the beauty of a finished frame, and
//! each of its split layers (light groups, path splits) on its own, through OIDN's
//! "RT" filter (`hdr`, with the `albedo` AOV as its auxiliary image; docs/sampling.md,
//! "Denoising", says why albedo and no normal).
//!
//! The library is loaded at run time (`dlopen`) from the file build.rs found
//! (`NIMBUS_OIDN`; the cfg `nimbus_oidn` says it found one), so nothing links against
//! it: the CLI, the Python module and the Hydra plug-in all load the same file, and a
//! build without it builds and runs (denoising is then an error, in one line).
//! `NIMBUS_OIDN_LIBRARY` at run time names another file (a machine the binary was
//! copied to: the Blender add-on points it at Blender's own OIDN).
//!
//! Denoising works on the channels as written (f32), so `render` on one machine and
//! `merge` of a farm's tiles denoise the same numbers and give the same image: tiles
//! are never denoised, the merge denoises the merged frame.

use super::denoise_mix;
use std::ffi::{c_char, c_void, CStr, CString};
use std::sync::OnceLock;
use std::time::Instant;

/// The channels of the auxiliary image: the albedo AOV ([`crate::render::film::Aov`]).
pub const ALBEDO: [&str; 3] = ["albedo.R", "albedo.G", "albedo.B"];
/// The layer the noisy beauty is kept in.
pub const NOISY: &str = "noisy";
/// The channels of the beauty's variance ([`crate::render::film::Aov::BeautyVarianceR`]):
/// the denoised values are mixed back towards the noisy ones by it
/// ([`super::denoise_mix`]).
pub const BEAUTY_VARIANCE: [&str; 3] = [
    "beauty_variance.R",
    "beauty_variance.G",
    "beauty_variance.B",
];
/// The sample-count channel ([`crate::render::film::Aov::Samples`]).
pub const SAMPLES: &str = "samples";

/// Whether this build can denoise: build.rs found OIDN (it may still fail to load).
pub fn built_in() -> bool {
    cfg!(nimbus_oidn)
}

/// The one-line error of a build without OIDN, or when a denoise is asked for and the
/// library cannot be loaded; `Ok` when it loads.
pub fn check_available() -> Result<(), String> {
    Oidn::get().map(|_| ())
}

/// What a denoise did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Denoised {
    /// RGB images denoised: the beauty and each split layer.
    pub images: usize,
    pub seconds: f64,
}

/// Denoises the `width` × `height` `channels` (row-major f32, named as the EXR
/// writes them) in place: R, G, B become the denoised beauty, the noisy one is kept
/// as `noisy.R/G/B`, and every split layer `NAME.R/G/B` (not the albedo) is
/// replaced by its own denoise (a layer black everywhere stays black). Each denoised
/// value is then mixed back towards its noisy one where the beauty's variance says
/// the denoiser's error is the larger ([`super::denoise_mix`]), with the beauty's
/// weights for every layer. A (alpha) and every other channel stay as they are.
/// Needs the albedo AOV ([`ALBEDO`]), the beauty variance ([`BEAUTY_VARIANCE`]) and
/// the sample counts ([`SAMPLES`]). Deterministic: the same channels give the
/// same result on the same machine (the input scale is computed here, not by OIDN's
/// threaded auto-exposure).
pub fn denoise_channels(
    width: usize,
    height: usize,
    channels: &mut Vec<(String, Vec<f32>)>,
) -> Result<Denoised, String> {
    let start = Instant::now();
    let find = |chans: &[(String, Vec<f32>)], name: &str| chans.iter().position(|c| c.0 == name);
    let rgb_of = |chans: &[(String, Vec<f32>)], names: [&str; 3]| names.map(|n| find(chans, n));
    let beauty = match rgb_of(channels, ["R", "G", "B"]) {
        [Some(r), Some(g), Some(b)] => [r, g, b],
        _ => return Err("denoising needs the beauty's R, G and B channels".into()),
    };
    let albedo = match rgb_of(channels, ALBEDO) {
        [Some(r), Some(g), Some(b)] => interleave(channels, [r, g, b]),
        _ => return Err("denoising needs the albedo AOV (albedo.R, .G, .B)".into()),
    };
    let (variance, samples) = match (rgb_of(channels, BEAUTY_VARIANCE), find(channels, SAMPLES)) {
        ([Some(r), Some(g), Some(b)], Some(s)) => ([r, g, b], s),
        _ => {
            return Err(
                "denoising needs the beauty_variance AOV (.R, .G, .B) and the samples AOV \
                 (a tile written by a build before them cannot be merged denoised)"
                    .into(),
            )
        }
    };
    if let Some(c) = channels.iter().find(|c| c.0.starts_with("noisy.")) {
        return Err(format!(
            "a channel {} already exists: the noisy beauty goes into the layer {NOISY}",
            c.0
        ));
    }
    let oidn = Oidn::get()?;
    let noisy = interleave(channels, beauty);
    // One scale for the beauty and every layer: each is then denoised at the exposure
    // it has in the beauty, as a part of it (and the scale does not depend on OIDN's
    // threads).
    let scale = input_scale(&noisy);
    let device = oidn.device()?;
    // The albedo is a Monte Carlo estimate too: denoised once on its own first (OIDN's
    // advice for noisy auxiliary images, Cycles' "Accurate" prefilter), then handed to
    // every filter below as clean.
    let albedo = device.prefilter_albedo(&albedo, width, height)?;
    let mut images = 1;
    let out = device.denoise(&noisy, &albedo, width, height, scale, "the beauty")?;
    let mut weights = Vec::with_capacity(3);
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        let mut denoised = deinterleave(&out, c);
        let kept = &channels[beauty[c]].1;
        let w = denoise_mix::noisy_weights(
            width,
            height,
            kept,
            &denoised,
            &channels[variance[c]].1,
            &channels[samples].1,
        );
        denoise_mix::mix(&mut denoised, kept, &w);
        weights.push(w);
        let kept = std::mem::replace(&mut channels[beauty[c]].1, denoised);
        channels.push((format!("{NOISY}.{name}"), kept));
    }
    for layer in split_layers(channels) {
        let idx = rgb_of(channels, layer_names(&layer).each_ref().map(|s| s.as_str()));
        let idx = idx.map(|i| i.expect("split_layers lists complete layers"));
        // A black layer (a light group whose lights light nothing here) stays exactly
        // black: the network would make a faint pattern of it, which a compositor
        // subtracting the layer (the add-on's transparent film) would see.
        if idx.iter().all(|&i| channels[i].1.iter().all(|&v| v == 0.0)) {
            continue;
        }
        let what = format!("the layer {layer}");
        let out = device.denoise(
            &interleave(channels, idx),
            &albedo,
            width,
            height,
            scale,
            &what,
        )?;
        for (c, &i) in idx.iter().enumerate() {
            let mut denoised = deinterleave(&out, c);
            denoise_mix::mix(&mut denoised, &channels[i].1, &weights[c]);
            channels[i].1 = denoised;
        }
        images += 1;
    }
    Ok(Denoised {
        images,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// `film`'s beauty (R, G, B, A), albedo AOV and split layers (`layers`: their names,
/// in the film's order) as named channels, denoised as [`denoise_channels`] does (the
/// Python module's `render(denoise=True)`, which writes no file).
pub fn denoise_film(
    film: &crate::render::film::Film,
    layers: &[String],
) -> Result<(Vec<(String, Vec<f32>)>, Denoised), String> {
    use crate::render::film::Aov;
    let mut channels: Vec<(String, Vec<f32>)> = [Aov::R, Aov::G, Aov::B, Aov::A]
        .into_iter()
        .chain(Aov::ALBEDO)
        .chain(Aov::BEAUTY_VARIANCE)
        .chain([Aov::Samples])
        .map(|a| (a.channel_name().to_string(), film.channel(a)))
        .collect();
    for (i, name) in layers.iter().enumerate() {
        let rgb = film.layer(i);
        for (c, v) in ["R", "G", "B"].into_iter().zip(rgb) {
            channels.push((format!("{name}.{c}"), v));
        }
    }
    let (w, h) = (film.width as usize, film.height as usize);
    let d = denoise_channels(w, h, &mut channels)?;
    Ok((channels, d))
}

fn layer_names(layer: &str) -> [String; 3] {
    ["R", "G", "B"].map(|c| format!("{layer}.{c}"))
}

/// The split layers among `channels`: every `NAME` with `NAME.R`, `.G` and `.B`, but
/// the albedo and the noisy beauty.
fn split_layers(channels: &[(String, Vec<f32>)]) -> Vec<String> {
    let mut layers: Vec<String> = Vec::new();
    for (name, _) in channels {
        let Some(layer) = name.strip_suffix(".R") else {
            continue;
        };
        let complete = layer_names(layer)
            .iter()
            .all(|n| channels.iter().any(|c| &c.0 == n));
        let auxiliary = ["albedo", "beauty_variance", NOISY].contains(&layer);
        if complete && !auxiliary && !layers.iter().any(|l| l == layer) {
            layers.push(layer.to_string());
        }
    }
    layers
}

/// Three channels as OIDN's FLOAT3 pixels, with what is not finite made finite as the
/// EXR writer does (a NaN or an infinity would spread through the network).
fn interleave(channels: &[(String, Vec<f32>)], idx: [usize; 3]) -> Vec<f32> {
    let n = channels[idx[0]].1.len();
    let mut out = Vec::with_capacity(n * 3);
    for p in 0..n {
        for &i in &idx {
            let v = channels[i].1[p];
            out.push(match v {
                v if v.is_finite() => v,
                v if v.is_nan() => 0.0,
                v => f32::MAX.copysign(v),
            });
        }
    }
    out
}

fn deinterleave(pixels: &[f32], c: usize) -> Vec<f32> {
    pixels.iter().skip(c).step_by(3).copied().collect()
}

/// OIDN's `inputScale` for an HDR image: its auto-exposure's rule (0.18 over the
/// geometric mean of the luminance of the pixels that are not black), computed in one
/// thread in f64 so that it is the same every time; 1 for a black image.
pub fn input_scale(pixels: &[f32]) -> f32 {
    let (mut sum, mut n) = (0.0f64, 0u64);
    for p in pixels.chunks_exact(3) {
        let l = crate::render::film::luminance([p[0] as f64, p[1] as f64, p[2] as f64]);
        if l > 1e-8 {
            sum += l.log2();
            n += 1;
        }
    }
    if n == 0 {
        return 1.0;
    }
    (0.18 / (sum / n as f64).exp2()) as f32
}

// ---- the library -----------------------------------------------------------------

type Handle = *mut c_void;

/// The OIDN 2.x C functions used (oidn.h), looked up once.
struct Oidn {
    new_device: unsafe extern "C" fn(i32) -> Handle,
    commit_device: unsafe extern "C" fn(Handle),
    release_device: unsafe extern "C" fn(Handle),
    get_device_error: unsafe extern "C" fn(Handle, *mut *const c_char) -> i32,
    new_filter: unsafe extern "C" fn(Handle, *const c_char) -> Handle,
    set_shared_filter_image: unsafe extern "C" fn(
        Handle,
        *const c_char,
        *mut c_void,
        i32,
        usize,
        usize,
        usize,
        usize,
        usize,
    ),
    set_filter_bool: unsafe extern "C" fn(Handle, *const c_char, bool),
    set_filter_float: unsafe extern "C" fn(Handle, *const c_char, f32),
    commit_filter: unsafe extern "C" fn(Handle),
    execute_filter: unsafe extern "C" fn(Handle),
    release_filter: unsafe extern "C" fn(Handle),
}

// The functions are plain C entry points of a library that is never unloaded.
unsafe impl Send for Oidn {}
unsafe impl Sync for Oidn {}

/// `OIDN_DEVICE_TYPE_CPU`: the CPU device, whatever GPU the machine has, so a frame
/// denoises the same on every machine of a farm with the same CPU.
const DEVICE_TYPE_CPU: i32 = 1;
/// `OIDN_FORMAT_FLOAT3`.
const FORMAT_FLOAT3: i32 = 3;

impl Oidn {
    /// The library, loaded on first use; the error says why not, in one line.
    fn get() -> Result<&'static Oidn, String> {
        static OIDN: OnceLock<Result<Oidn, String>> = OnceLock::new();
        OIDN.get_or_init(Oidn::load).as_ref().map_err(Clone::clone)
    }

    fn load() -> Result<Oidn, String> {
        let built = option_env!("NIMBUS_OIDN_LIBRARY");
        if !built_in() || built.is_none() {
            return Err(
                "denoising is not built in: Open Image Denoise was not found when \
                        nimbus was built; install it (`bash .ci/setup`, or `pip install pyoidn`) \
                        and build again with NIMBUS_OIDN=require"
                    .into(),
            );
        }
        let path = std::env::var("NIMBUS_OIDN_LIBRARY")
            .ok()
            .filter(|p| !p.is_empty())
            .or(built.map(String::from))
            .unwrap_or_default();
        let lib = dlopen(&path)?;
        let sym = |name: &str| -> Result<*mut c_void, String> {
            let c = CString::new(name).map_err(|e| e.to_string())?;
            // SAFETY: `lib` is a live handle and `c` a NUL-terminated name.
            let p = unsafe { libc::dlsym(lib, c.as_ptr()) };
            if p.is_null() {
                Err(format!("{path} has no {name}: not Open Image Denoise 2.x"))
            } else {
                Ok(p)
            }
        };
        // SAFETY: each symbol is OIDN 2.x's function of that name, whose C signature
        // (oidn.h) the field's type repeats.
        unsafe {
            Ok(Oidn {
                new_device: std::mem::transmute(sym("oidnNewDevice")?),
                commit_device: std::mem::transmute(sym("oidnCommitDevice")?),
                release_device: std::mem::transmute(sym("oidnReleaseDevice")?),
                get_device_error: std::mem::transmute(sym("oidnGetDeviceError")?),
                new_filter: std::mem::transmute(sym("oidnNewFilter")?),
                set_shared_filter_image: std::mem::transmute(sym("oidnSetSharedFilterImage")?),
                set_filter_bool: std::mem::transmute(sym("oidnSetFilterBool")?),
                set_filter_float: std::mem::transmute(sym("oidnSetFilterFloat")?),
                commit_filter: std::mem::transmute(sym("oidnCommitFilter")?),
                execute_filter: std::mem::transmute(sym("oidnExecuteFilter")?),
                release_filter: std::mem::transmute(sym("oidnReleaseFilter")?),
            })
        }
    }

    /// A committed CPU device.
    fn device(&'static self) -> Result<Device, String> {
        // SAFETY: OIDN functions on handles this code owns; errors are read back.
        let handle = unsafe { (self.new_device)(DEVICE_TYPE_CPU) };
        if handle.is_null() {
            return Err("Open Image Denoise could not create a CPU device".into());
        }
        let device = Device { oidn: self, handle };
        unsafe { (self.commit_device)(handle) };
        device.check("creating the CPU device")?;
        Ok(device)
    }
}

fn dlopen(path: &str) -> Result<Handle, String> {
    let c = CString::new(path).map_err(|e| e.to_string())?;
    // SAFETY: a NUL-terminated path; the handle is kept for the process' life.
    let lib = unsafe { libc::dlopen(c.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL) };
    if lib.is_null() {
        // SAFETY: dlerror returns a message owned by libc, or NULL.
        let why = unsafe { libc::dlerror() };
        let why = match why.is_null() {
            true => "unknown error".to_string(),
            false => unsafe { CStr::from_ptr(why) }
                .to_string_lossy()
                .into_owned(),
        };
        return Err(format!(
            "cannot load Open Image Denoise ({why}); set NIMBUS_OIDN_LIBRARY to its libOpenImageDenoise.so.2"
        ));
    }
    Ok(lib)
}

struct Device {
    oidn: &'static Oidn,
    handle: Handle,
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: the device this struct created, released once.
        unsafe { (self.oidn.release_device)(self.handle) }
    }
}

struct Filter<'a> {
    device: &'a Device,
    handle: Handle,
}

impl Drop for Filter<'_> {
    fn drop(&mut self) {
        // SAFETY: the filter this struct created, released once.
        unsafe { (self.device.oidn.release_filter)(self.handle) }
    }
}

impl Device {
    /// OIDN's error since the last check, as `Err` naming `what` was being done.
    fn check(&self, what: &str) -> Result<(), String> {
        let mut message: *const c_char = std::ptr::null();
        // SAFETY: a live device; the message is owned by OIDN until the next call.
        let code = unsafe { (self.oidn.get_device_error)(self.handle, &mut message) };
        if code == 0 {
            return Ok(());
        }
        let text = match message.is_null() {
            true => String::new(),
            false => unsafe { CStr::from_ptr(message) }
                .to_string_lossy()
                .into_owned(),
        };
        Err(format!(
            "Open Image Denoise failed {what} (error {code}: {text})"
        ))
    }

    /// The albedo AOV (FLOAT3 pixels) denoised by the RT filter on its own (no colour
    /// image: OIDN's auxiliary prefilter), so the beauty's filters may take it as
    /// clean.
    fn prefilter_albedo(
        &self,
        albedo: &[f32],
        width: usize,
        height: usize,
    ) -> Result<Vec<f32>, String> {
        self.rt_filter(None, albedo, width, height, "the albedo AOV")
    }

    /// `color` (FLOAT3 pixels) denoised by the RT filter with the prefiltered
    /// `albedo`, HDR, at `scale`; `what` names the image in errors.
    fn denoise(
        &self,
        color: &[f32],
        albedo: &[f32],
        width: usize,
        height: usize,
        scale: f32,
        what: &str,
    ) -> Result<Vec<f32>, String> {
        self.rt_filter(Some((color, scale)), albedo, width, height, what)
    }

    /// One run of OIDN's RT filter: with `color` (and its HDR input scale), `color`
    /// denoised with `albedo` as its clean auxiliary image; without, `albedo` itself
    /// denoised (the auxiliary prefilter).
    fn rt_filter(
        &self,
        color: Option<(&[f32], f32)>,
        albedo: &[f32],
        width: usize,
        height: usize,
        what: &str,
    ) -> Result<Vec<f32>, String> {
        let n = width * height * 3;
        let given = color.map_or(albedo.len(), |(c, _)| c.len());
        if given != n || albedo.len() != n {
            return Err(format!(
                "{what}: {given} values for a {width}x{height} image"
            ));
        }
        let mut color_image = color.map(|(c, _)| c.to_vec());
        let mut albedo = albedo.to_vec();
        let mut output = vec![0f32; n];
        let rt = CString::new("RT").expect("no NUL");
        // SAFETY: a live device; the images outlive the filter (dropped at the end of
        // this function) and are `width × height` FLOAT3 pixels, tightly packed.
        let handle = unsafe { (self.oidn.new_filter)(self.handle, rt.as_ptr()) };
        if handle.is_null() {
            self.check("creating the RT filter")?;
            return Err("Open Image Denoise has no RT filter".into());
        }
        let filter = Filter {
            device: self,
            handle,
        };
        let o = self.oidn;
        let name = |s: &str| CString::new(s).expect("no NUL");
        let mut images = vec![
            ("albedo", albedo.as_mut_ptr()),
            ("output", output.as_mut_ptr()),
        ];
        if let Some(c) = color_image.as_mut() {
            images.push(("color", c.as_mut_ptr()));
        }
        unsafe {
            for (image, data) in images {
                let key = name(image);
                (o.set_shared_filter_image)(
                    filter.handle,
                    key.as_ptr(),
                    data.cast(),
                    FORMAT_FLOAT3,
                    width,
                    height,
                    0,
                    0,
                    0,
                );
            }
            if let Some((_, scale)) = color {
                (o.set_filter_bool)(filter.handle, name("hdr").as_ptr(), true);
                // Prefiltered above.
                (o.set_filter_bool)(filter.handle, name("cleanAux").as_ptr(), true);
                (o.set_filter_float)(filter.handle, name("inputScale").as_ptr(), scale);
            }
            (o.commit_filter)(filter.handle);
        }
        self.check(&format!("setting up the RT filter for {what}"))?;
        unsafe { (o.execute_filter)(filter.handle) };
        self.check(&format!("denoising {what}"))?;
        drop(filter);
        Ok(output)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_layers_are_complete_rgb_triples_but_albedo_variance_and_noisy() {
        let c = |n: &str| (n.to_string(), vec![0.0f32]);
        let chans = vec![
            c("R"),
            c("G"),
            c("B"),
            c("A"),
            c("albedo.R"),
            c("albedo.G"),
            c("albedo.B"),
            c("beauty_variance.R"),
            c("beauty_variance.G"),
            c("beauty_variance.B"),
            c("key.R"),
            c("key.G"),
            c("key.B"),
            c("half.R"),
            c("noisy.R"),
            c("noisy.G"),
            c("noisy.B"),
        ];
        assert_eq!(split_layers(&chans), vec!["key".to_string()]);
    }

    #[test]
    fn the_input_scale_maps_the_geometric_mean_to_0_18() {
        let px = [2.0f32, 2.0, 2.0, 8.0, 8.0, 8.0, 0.0, 0.0, 0.0];
        // Geometric mean of 2 and 8 is 4 (the black pixel is left out).
        assert!((input_scale(&px) - 0.045).abs() < 1e-6);
        assert_eq!(input_scale(&[0.0; 6]), 1.0);
    }

    #[test]
    fn missing_albedo_is_an_error_not_a_panic() {
        let mut chans = vec![
            ("R".to_string(), vec![0.0f32]),
            ("G".to_string(), vec![0.0f32]),
            ("B".to_string(), vec![0.0f32]),
        ];
        let e = denoise_channels(1, 1, &mut chans).unwrap_err();
        assert!(e.contains("albedo"), "{e}");
    }
}

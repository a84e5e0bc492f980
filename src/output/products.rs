//! The files a render writes: one EXR per RenderProduct (or the `-o` image of a stage
//! without products) with its RenderVars' channels, the stats JSON and the preview
//! PNGs; their names for a frame of a sequence; and writing them all for the samples
//! done so far (after the last pass, and at every checkpoint).

use super::deep::{deep_samples, write_deep_exr, DeepImage, DepthBin};
use super::denoise::denoise_channels;
use super::exr::{write_channels, Denoise, ExrMetadata, FarmMetadata};
use super::preview::{write_preview, write_preview_rgb};
use super::stats::{RenderStats, RunFacts};
use super::{check_writable, write_atomically, OutputError};
use crate::render::film::{Aov, Film};
use crate::render::progressive::Progress;
use crate::render::session::Session;
use crate::render::splits::SplitLayer;
use crate::render::tiles::Tile;
use crate::scene::{RenderSettings, RenderVar};
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// One EXR to write: a RenderProduct (or the `-o` image of a stage without one) and
/// its channels.
#[derive(Clone, Debug)]
pub struct ProductOutput {
    pub path: PathBuf,
    /// The RenderProduct prim, `None` for the `-o` image of a stage without products.
    pub prim_path: Option<String>,
    pub aovs: Vec<Aov>,
    /// Split layers (light groups, path splits): RGB channels `name.R`, `.G`, `.B`.
    pub layers: Vec<SplitLayer>,
    /// The product's preview PNG (`nimbus:previewName`, or `--preview` for the first).
    pub preview: Option<PathBuf>,
    /// A deep scanline EXR (`productType = "deepRaster"`, or `--deep`): Z, ZBack and
    /// premultiplied RGBA per sample instead of flat channels.
    pub deep: bool,
}

impl ProductOutput {
    /// Whether denoising applies to this product: a flat EXR with the beauty. A deep
    /// one is written as it is; every flat product has R, G, B, A today
    /// ([`product_outputs`]), and the check keeps one without them from failing the
    /// render only when it is written, at its end.
    fn denoised(&self) -> bool {
        !self.deep
            && [Aov::R, Aov::G, Aov::B]
                .iter()
                .all(|a| self.aovs.contains(a))
    }
}

/// Everything a render writes.
#[derive(Clone, Debug)]
pub struct Outputs {
    pub products: Vec<ProductOutput>,
    pub stats: Option<PathBuf>,
    /// The tile these files are (`None` for a whole frame).
    pub tile: Option<Tile>,
    /// Whether the EXRs carry the farm metadata (tiles and explicit regions).
    pub farm: bool,
    /// Deep samples per pixel at most.
    pub deep_samples: usize,
    /// Denoise the flat EXRs (a tile's are not: its merge denoises the frame);
    /// [`Outputs::set_denoise`].
    pub denoise: bool,
}

/// Deep samples per pixel at most, unless asked otherwise.
pub const DEFAULT_DEEP_SAMPLES: usize = 32;

/// What the caller asks to write beyond the stage's products.
#[derive(Clone, Debug, Default)]
pub struct OutputRequest {
    /// Replaces the first product's path; needed when the stage has no product.
    pub output: Option<PathBuf>,
    /// Extra AOVs for the first product.
    pub aovs: Vec<Aov>,
    /// Extra split layers for the first product.
    pub layers: Vec<SplitLayer>,
    /// A deep EXR of the beauty to write too (`--deep`).
    pub deep: Option<PathBuf>,
    /// Deep samples per pixel at most (`--deep-samples`; 0: [`DEFAULT_DEEP_SAMPLES`]).
    pub deep_samples: usize,
    pub stats: Option<PathBuf>,
    /// A preview PNG of the first product.
    pub preview: Option<PathBuf>,
    /// Tile of a farm task: every file name gets `.tileII`, and the EXRs the tile's
    /// metadata (`merge` assembles them).
    pub tile: Option<Tile>,
    /// An explicit pixel region (`--region`): the EXRs record the farm metadata too.
    pub region: bool,
}

impl Outputs {
    /// The files a render of `settings` writes, named for `frame` when it is a frame
    /// of a sequence (`sequence`), else for a whole single frame only where a name asks
    /// for it with `#`; checked to be distinct and writable before anything renders.
    pub fn resolve(
        stage: &Path,
        settings: &RenderSettings,
        request: &OutputRequest,
        frame: Option<f64>,
        sequence: bool,
    ) -> Result<Outputs> {
        let single = frame.filter(|t| t.fract() == 0.0 && t.abs() < 1e15);
        let frame_name = |p: &PathBuf| match (sequence, single) {
            (true, Some(f)) => frame_path(p, f as i64),
            (false, Some(t)) if p.to_string_lossy().contains('#') => frame_path(p, t as i64),
            _ => p.clone(),
        };
        let name = |p: &PathBuf| {
            let p = frame_name(p);
            match (request.tile, p.file_name()) {
                (Some(t), Some(n)) => p.with_file_name(t.file_name(&n.to_string_lossy())),
                _ => p,
            }
        };
        let stats = request.stats.as_ref().map(name);
        if let Some(s) = &stats {
            check_writable(s)?;
        }
        let products: Vec<ProductOutput> = product_outputs(request, settings)
            .with_context(|| format!("{}", stage.display()))?
            .into_iter()
            .map(|o| ProductOutput {
                path: name(&o.path),
                preview: o.preview.as_ref().map(name),
                ..o
            })
            .collect();
        let outputs = Outputs {
            products,
            stats,
            tile: request.tile,
            farm: request.tile.is_some() || request.region,
            deep_samples: match request.deep_samples {
                0 => DEFAULT_DEEP_SAMPLES,
                n => n,
            },
            denoise: false,
        };
        outputs.check_distinct()?;
        for o in &outputs.products {
            check_writable(&o.path)?;
            if let Some(p) = &o.preview {
                check_writable(p)?;
            }
        }
        Ok(outputs)
    }

    /// Whether every EXR this render writes already exists, complete (all the samples
    /// asked for) and from the same settings (`nimbus:settingsHash`): a farm task
    /// whose output is valid has nothing to do. Only for outputs with farm metadata.
    pub fn complete(&self, session: &Session) -> bool {
        let hash = format!("{:016x}", session.settings_hash());
        self.farm
            && self.products.iter().all(|o| {
                let text = |k| super::exr::read_text_attribute(&o.path, k).ok().flatten();
                let int = |k| super::exr::read_i32_attribute(&o.path, k).ok().flatten();
                o.path.is_file()
                    && text("nimbus:settingsHash").as_deref() == Some(hash.as_str())
                    && int("nimbus:spp").is_some()
                    && int("nimbus:spp") == int("nimbus:sppCap")
            })
    }

    /// Denoises the flat EXRs when `denoise` (the session's): each gets the albedo AOV
    /// (the denoiser's auxiliary image), the beauty variance and the sample counts
    /// (which mix the denoised values back towards the noisy ones; a tile carries all
    /// three for its merge), and a frame
    /// that is not a tile checks that Open Image Denoise loads, before anything
    /// renders (a build without it fails here, in one line).
    pub fn set_denoise(&mut self, denoise: bool) -> Result<()> {
        self.denoise = denoise;
        if !denoise {
            return Ok(());
        }
        if self.tile.is_none() {
            super::denoise::check_available().map_err(anyhow::Error::msg)?;
        }
        for o in self.products.iter_mut().filter(|o| o.denoised()) {
            for a in Aov::ALBEDO
                .into_iter()
                .chain(Aov::BEAUTY_VARIANCE)
                .chain([Aov::Samples])
            {
                if !o.aovs.contains(&a) {
                    o.aovs.push(a);
                }
            }
        }
        Ok(())
    }

    /// Every split layer some product writes, each once, in the order the film holds
    /// them.
    pub fn split_layers(&self) -> Vec<SplitLayer> {
        let mut layers: Vec<SplitLayer> = Vec::new();
        for l in self.products.iter().flat_map(|o| &o.layers) {
            if !layers.contains(l) {
                layers.push(l.clone());
            }
        }
        layers
    }

    /// Whether some product is a deep EXR.
    pub fn deep(&self) -> bool {
        self.products.iter().any(|o| o.deep)
    }

    /// Whether anything written reads the per-pixel counters (then counting runs).
    pub fn need_counts(&self) -> bool {
        self.stats.is_some()
            || self
                .products
                .iter()
                .any(|o| o.aovs.iter().any(|a| a.uses_counters()))
    }

    /// Writes every EXR, preview and the stats for the samples in `film` so far.
    pub fn write(
        &self,
        session: &Session,
        film: &Film,
        run: &RunFacts,
        p: &Progress,
    ) -> Result<()> {
        let t = &session.tracking;
        let all_layers = self.split_layers();
        if film.layer_count != all_layers.len() {
            bail!(
                "the render did not compute the split AOVs {} (its job was made without them)",
                all_layers
                    .iter()
                    .map(|l| l.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        let mut denoise_seconds = 0.0;
        for o in &self.products {
            let mut meta = ExrMetadata {
                stage: session.stage_path.display().to_string(),
                tracker: t.tracker.name().into(),
                scheme: t.scheme.name().into(),
                transmittance: t.transmittance.name().into(),
                spp: p.spp,
                render_seconds: p.seconds,
                time: session.frame.unwrap_or(f64::NAN),
                product: o.prim_path.clone(),
                denoise: Denoise::Off,
                farm: self.farm.then(|| FarmMetadata {
                    seed: session.seed,
                    spp_cap: (session.spp != u32::MAX).then_some(session.spp),
                    settings_hash: session.settings_hash(),
                    tile: self.tile,
                }),
            };
            if o.deep {
                write_deep(&o.path, film, self.deep_samples, &meta)?;
                continue;
            }
            let mut channels: Vec<(String, Vec<f32>)> = o
                .aovs
                .iter()
                .map(|&a| (a.channel_name().to_string(), film.channel(a)))
                .collect();
            for layer in &o.layers {
                let i = all_layers.iter().position(|l| l == layer).unwrap_or(0);
                let [r, g, b] = film.layer(i);
                for (c, v) in ["R", "G", "B"].into_iter().zip([r, g, b]) {
                    channels.push((format!("{}.{c}", layer.name), v));
                }
            }
            if self.denoise && o.denoised() {
                meta.denoise = match self.tile {
                    Some(_) => Denoise::ByMerge,
                    None => {
                        let (w, h) = (film.width as usize, film.height as usize);
                        let d = denoise_channels(w, h, &mut channels)
                            .map_err(|e| anyhow::anyhow!("{}: {e}", o.path.display()))?;
                        denoise_seconds += d.seconds;
                        Denoise::Done
                    }
                };
            }
            let preview_rgb = match (&o.preview, meta.denoise) {
                (Some(_), Denoise::Done) => Some(["R", "G", "B"].map(|n| {
                    channels
                        .iter()
                        .find(|c| c.0 == n)
                        .map(|c| c.1.clone())
                        .unwrap_or_default()
                })),
                _ => None,
            };
            write_channels(&o.path, film.full, film.region, channels, &meta)?;
            match (&o.preview, preview_rgb) {
                (Some(preview), Some([r, g, b])) => {
                    write_preview_rgb(preview, (film.width, film.height), [&r, &g, &b])?
                }
                (Some(preview), None) => write_preview(preview, film)?,
                (None, _) => {}
            }
        }
        if let Some(path) = &self.stats {
            let mut stats = RenderStats::new(session, film, p, run);
            stats.denoise = match (self.denoise, self.tile) {
                (false, _) => None,
                (true, Some(_)) => Denoise::ByMerge.attribute(),
                (true, None) => Denoise::Done.attribute(),
            };
            stats.denoise_seconds = denoise_seconds;
            write_json(path, &stats)?;
        }
        Ok(())
    }

    /// The paths written, for messages.
    pub fn list(&self) -> String {
        self.products
            .iter()
            .flat_map(|o| std::iter::once(&o.path).chain(o.preview.as_ref()))
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Two products writing one file would overwrite each other.
    fn check_distinct(&self) -> Result<()> {
        let o = &self.products;
        for (i, a) in o.iter().enumerate() {
            if let Some(b) = o[..i].iter().find(|b| b.path == a.path) {
                bail!(
                    "{} and {} both write {}",
                    b.prim_path.as_deref().unwrap_or("-o"),
                    a.prim_path.as_deref().unwrap_or("-o"),
                    a.path.display()
                );
            }
        }
        Ok(())
    }
}

/// Writes the film's beauty as a deep EXR of at most `limit` samples per pixel: each
/// pixel's depth bins (the mean radiance and alpha of the samples whose first real
/// collision on the camera ray fell in each camera-depth slab, and of those with none
/// at the back) become `over`-composited samples that flatten to the flat beauty.
fn write_deep(path: &Path, film: &Film, limit: usize, meta: &ExrMetadata) -> Result<()> {
    if film.depth_bins.is_none() {
        bail!(
            "{}: the render did not bin its samples by depth (its job was made without deep output)",
            path.display()
        );
    }
    let mut counts = Vec::with_capacity(film.pixels.len());
    let mut samples = Vec::new();
    let mut bins = Vec::new();
    for p in 0..film.pixels.len() {
        bins.clear();
        bins.extend(
            film.deep_bins(p)
                .into_iter()
                .map(|((z, z_back), rgb, alpha)| DepthBin {
                    z,
                    z_back,
                    rgb,
                    alpha,
                }),
        );
        let before = samples.len();
        deep_samples(&bins, limit, &mut samples);
        counts.push((samples.len() - before) as u32);
    }
    let mut attributes = vec![
        (
            "nimbus:version".to_string(),
            env!("CARGO_PKG_VERSION").to_string(),
        ),
        ("nimbus:stage".to_string(), meta.stage.clone()),
        ("nimbus:tracker".to_string(), meta.tracker.clone()),
        ("nimbus:spp".to_string(), meta.spp.to_string()),
        ("nimbus:deepSamples".to_string(), limit.to_string()),
    ];
    if let Some(product) = &meta.product {
        attributes.push(("nimbus:renderProduct".to_string(), product.clone()));
    }
    let image = DeepImage {
        full: film.full,
        region: film.region,
        counts,
        samples,
        attributes,
    };
    write_deep_exr(path, &image)?;
    Ok(())
}

/// Writes `value` as pretty JSON, atomically.
pub fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<(), OutputError> {
    let json = serde_json::to_string_pretty(value).map_err(|e| OutputError::Write {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    write_atomically(path, |f| {
        use std::io::Write;
        f.write_all(json.as_bytes()).map_err(|e| e.to_string())
    })
}

/// The AOVs and split layers `names` name (`--aovs`), without repeats: split names
/// (`direct`, `indirect`, `emission`, `lightgroup:GROUP`) become layers named after them
/// (`lightgroup:key` → `lightgroup_key`).
pub fn requested_outputs(names: &[String]) -> Result<(Vec<Aov>, Vec<SplitLayer>)> {
    let mut layers = Vec::new();
    let mut others = Vec::new();
    for n in names.iter().map(|n| n.trim()) {
        match split_shorthand(&layer_name(n), n) {
            Some(l) => add_layers(&mut layers, "--aovs", l)?,
            None => others.push(n.to_string()),
        }
    }
    Ok((requested_aovs(&others)?, layers))
}

/// The split layer a shorthand (`direct`, `indirect`, `emission`, `lightgroup:GROUP`)
/// names, as layer `layer`; `None` for any other name (no AOV name is a shorthand).
fn split_shorthand(layer: &str, name: &str) -> Option<SplitLayer> {
    SplitLayer::parse(layer, name, "raw").ok()
}

/// An EXR layer name for a split shorthand: characters other than letters, digits
/// and `_` become `_`.
fn layer_name(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The AOVs `names` name (`--aovs`), without repeats.
pub fn requested_aovs(names: &[String]) -> Result<Vec<Aov>> {
    let mut aovs = Vec::new();
    for n in names.iter().map(|n| n.trim()).filter(|n| !n.is_empty()) {
        let Some(a) = Aov::from_name(n) else {
            let known: Vec<_> = Aov::ALL.iter().map(|a| a.channel_name()).collect();
            bail!(
                "unknown AOV '{n}'; known AOVs: {}, and the splits direct, indirect, emission, lightgroup:GROUP",
                known.join(", ")
            );
        };
        if !aovs.contains(&a) {
            aovs.push(a);
        }
    }
    Ok(aovs)
}

/// The EXRs to write. Without RenderProducts: `-o` with R, G, B, A, lookups and the
/// extra AOVs. With them: one EXR per product at its `productName` (relative names are
/// relative to the working directory, as for `-o`), `-o` replacing the first product's;
/// each holds R, G, B, A and the channels of its own RenderVars, and the first also the
/// extra AOVs and the requested preview.
fn product_outputs(
    request: &OutputRequest,
    settings: &RenderSettings,
) -> Result<Vec<ProductOutput>> {
    let output = request.output.as_deref();
    if settings.products.is_empty() {
        let Some(path) = output else {
            bail!("no output: the stage has no RenderProduct, so give one with -o OUT.exr");
        };
        let mut aovs = Aov::DEFAULT.to_vec();
        add_aovs(&mut aovs, &request.aovs);
        let mut outputs = vec![ProductOutput {
            path: path.to_path_buf(),
            prim_path: None,
            aovs,
            layers: request.layers.clone(),
            preview: request.preview.clone(),
            deep: false,
        }];
        outputs.extend(deep_request(request));
        return Ok(outputs);
    }
    let mut outputs = Vec::new();
    for (i, product) in settings.products.iter().enumerate() {
        let path = match (i, output, &product.product_name) {
            (0, Some(o), _) => o.to_path_buf(),
            (_, _, Some(name)) => PathBuf::from(name),
            (_, _, None) => bail!(
                "{}: RenderProduct has no productName{}",
                product.prim_path,
                if i == 0 {
                    "; give the output with -o"
                } else {
                    ""
                }
            ),
        };
        let mut aovs = vec![Aov::R, Aov::G, Aov::B, Aov::A];
        let mut layers = Vec::new();
        for var in &product.vars {
            match render_var_output(var)? {
                VarOutput::Aovs(a) => add_aovs(&mut aovs, &a),
                VarOutput::Layer(l) => add_layers(&mut layers, &var.prim_path, l)?,
            }
        }
        let mut preview = product.preview_name.as_ref().map(PathBuf::from);
        if i == 0 {
            add_aovs(&mut aovs, &request.aovs);
            for l in &request.layers {
                add_layers(&mut layers, "--aovs", l.clone())?;
            }
            preview = request.preview.clone().or(preview);
        }
        let deep = product.product_type == "deepRaster";
        if deep {
            // A deep image holds depth, colour and alpha per sample, nothing else.
            let extra: Vec<&str> = aovs
                .iter()
                .filter(|a| !matches!(a, Aov::R | Aov::G | Aov::B | Aov::A))
                .map(|a| a.channel_name())
                .chain(layers.iter().map(|l| l.name.as_str()))
                .collect();
            if !extra.is_empty() {
                bail!(
                    "{}: a deepRaster product holds colour and alpha only; move {} to a raster product",
                    product.prim_path,
                    extra.join(", ")
                );
            }
        }
        outputs.push(ProductOutput {
            path,
            prim_path: Some(product.prim_path.clone()),
            aovs,
            layers,
            preview: preview.filter(|_| !deep),
            deep,
        });
    }
    outputs.extend(deep_request(request));
    Ok(outputs)
}

/// The `--deep` image, if asked for: a deep EXR of the beauty.
fn deep_request(request: &OutputRequest) -> Option<ProductOutput> {
    request.deep.as_ref().map(|path| ProductOutput {
        path: path.clone(),
        prim_path: None,
        aovs: vec![Aov::R, Aov::G, Aov::B, Aov::A],
        layers: Vec::new(),
        preview: None,
        deep: true,
    })
}

/// Adds split layer `l` (from `what`) unless the same layer is there; two different
/// layers of one name would write the same channels.
fn add_layers(layers: &mut Vec<SplitLayer>, what: &str, l: SplitLayer) -> Result<()> {
    match layers.iter().find(|x| x.name == l.name) {
        Some(x) if *x == l => Ok(()),
        Some(_) => bail!(
            "{what}: two split AOVs named '{}' in one product (RenderVar names become EXR layer names)",
            l.name
        ),
        None => {
            layers.push(l);
            Ok(())
        }
    }
}

fn add_aovs(aovs: &mut Vec<Aov>, more: &[Aov]) {
    for &a in more {
        if !aovs.contains(&a) {
            aovs.push(a);
        }
    }
}

/// What a RenderVar writes: film channels, or a split layer.
enum VarOutput {
    Aovs(Vec<Aov>),
    Layer(SplitLayer),
}

/// A RenderVar's output. A light path expression (`sourceType = "lpe"`) or a split
/// shorthand (`direct`, `indirect`, `emission`, `lightgroup:GROUP`) is a split layer
/// named after the RenderVar prim (USD names an AOV by its RenderVar); anything else
/// is one of the film's channels ([`render_var_aovs`]).
fn render_var_output(var: &RenderVar) -> Result<VarOutput> {
    let var_name = var.prim_path.rsplit('/').next().unwrap_or(&var.prim_path);
    let source = var.source_name.trim();
    if var.source_type == "lpe" {
        return SplitLayer::parse(var_name, source, "lpe")
            .map(VarOutput::Layer)
            .map_err(|e| anyhow::anyhow!("{}: {e}", var.prim_path));
    }
    match split_shorthand(var_name, source) {
        Some(l) => Ok(VarOutput::Layer(l)),
        None => render_var_aovs(var).map(VarOutput::Aovs),
    }
}

/// The channels a RenderVar names: `color` (also `C`, `Ci`, `rgb`) is R, G, B;
/// `alpha`/`a` is A; the other AOVs go by their channel names.
fn render_var_aovs(var: &RenderVar) -> Result<Vec<Aov>> {
    let name = var.source_name.trim();
    Ok(match name {
        "color" | "C" | "Ci" | "rgb" | "RGB" => vec![Aov::R, Aov::G, Aov::B],
        "alpha" | "a" | "A" => vec![Aov::A],
        other => match Aov::from_name(other) {
            Some(a) => vec![a],
            None => {
                let known: Vec<_> = Aov::ALL.iter().map(|a| a.channel_name()).collect();
                bail!(
                    "{}: sourceName \"{other}\" is not an AOV Nimbus knows; known: color, alpha, {}, the splits direct, indirect, emission, lightgroup:GROUP, or a light path expression with sourceType \"lpe\"",
                    var.prim_path,
                    known.join(", ")
                );
            }
        },
    })
}

/// The output path of `frame` in a sequence: the first run of `#` in the file name
/// becomes the frame number zero-padded to the run's length; without one, `.NNNN`
/// (four digits at least) goes before the extension.
pub fn frame_path(path: &Path, frame: i64) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let number = |width: usize| {
        if frame < 0 {
            format!(
                "-{:0width$}",
                frame.unsigned_abs(),
                width = width.saturating_sub(1)
            )
        } else {
            format!("{frame:0width$}")
        }
    };
    let new_name = match name.find('#') {
        Some(start) => {
            let len = name[start..].chars().take_while(|&c| c == '#').count();
            format!("{}{}{}", &name[..start], number(len), &name[start + len..])
        }
        None => match name.rfind('.').filter(|&i| i > 0) {
            Some(dot) => format!("{}.{}{}", &name[..dot], number(4), &name[dot..]),
            None => format!("{name}.{}", number(4)),
        },
    };
    path.with_file_name(new_name)
}

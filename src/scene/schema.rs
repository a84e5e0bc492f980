//! Registration of Nimbus' codeless schema (`schemas/`) with openusd's schema registry.
//!
//! Pixar's USD discovers the schema through `schemas/plugInfo.json` (point
//! `PXR_PLUGINPATH_NAME` at the directory). openusd has no plugin system, so the
//! same two files are compiled into the binary and handed to a
//! [`SchemaRegistryBuilder`] as a schema *family*:
//!
//! - the schematics layer is `generatedSchema.usda` verbatim, which carries every
//!   property with its fallback value;
//! - the manifest layer (schema kind, bases, apply restrictions — what C++ keeps in
//!   `plugInfo.json`) is derived from `plugInfo.json` at run time, so the two
//!   implementations can never disagree about what the schema is.
//!
//! The resulting registry also holds every family `openusd_schemas` enables, so a
//! stage opened with it resolves UsdGeom/UsdLux/UsdRender/UsdVol fallbacks too.

use std::fmt::Write as _;
use std::sync::{Arc, OnceLock};

use openusd::sdf;
use openusd::usd::{FamilySource, SchemaRegistry};

/// `schemas/generatedSchema.usda`, embedded so the binary works from anywhere.
pub const GENERATED_SCHEMA: &str = include_str!("../../schemas/generatedSchema.usda");
/// `schemas/plugInfo.json`, embedded for the same reason.
pub const PLUG_INFO: &str = include_str!("../../schemas/plugInfo.json");

/// The family name the schema registers under (plugInfo's plugin `Name`).
pub const FAMILY: &str = "nimbusSchema";

/// Single-apply API schema carrying the medium parameters of a Volume.
pub const VOLUME_API: &str = "NimbusVolumeAPI";
/// Single-apply API schema carrying the integrator settings of a RenderSettings prim.
pub const RENDER_SETTINGS_API: &str = "NimbusRenderSettingsAPI";

/// Single-apply API schema of a UsdGeom gprim: `nimbus:holdout` (whether it renders as
/// a black matte occluder). The attribute is read whether or not the schema is applied.
pub const HOLDOUT_API: &str = "NimbusHoldoutAPI";

/// Property names of [`VOLUME_API`], [`RENDER_SETTINGS_API`] and [`HOLDOUT_API`].
pub mod tokens {
    pub const DENSITY_FIELD: &str = "nimbus:densityField";
    pub const DENSITY_SCALE: &str = "nimbus:densityScale";
    pub const ABSORPTION: &str = "nimbus:absorption";
    pub const SCATTERING: &str = "nimbus:scattering";
    pub const ANISOTROPY: &str = "nimbus:anisotropy";
    pub const TEMPERATURE_FIELD: &str = "nimbus:temperatureField";
    pub const TEMPERATURE_SCALE: &str = "nimbus:temperatureScale";
    pub const BLACKBODY_INTENSITY: &str = "nimbus:blackbodyIntensity";
    pub const EMISSION_FIELD: &str = "nimbus:emissionField";
    pub const EMISSION_COLOR: &str = "nimbus:emissionColor";
    pub const EMISSION_SCALE: &str = "nimbus:emissionScale";
    pub const EMISSION_KIND: &str = "nimbus:emissionKind";
    pub const ALBEDO_FIELD: &str = "nimbus:albedoField";
    pub const ALBEDO: &str = "nimbus:albedo";
    pub const VELOCITY_FIELD: &str = "nimbus:velocityField";
    pub const VELOCITY_SCALE: &str = "nimbus:velocityScale";
    pub const SAMPLES: &str = "nimbus:samples";
    pub const MIN_SAMPLES: &str = "nimbus:minSamples";
    pub const NOISE_THRESHOLD: &str = "nimbus:noiseThreshold";
    pub const DENOISE: &str = "nimbus:denoise";
    pub const MAX_DEPTH: &str = "nimbus:maxDepth";
    pub const SEED: &str = "nimbus:seed";
    pub const TRACKER: &str = "nimbus:tracker";
    pub const SCHEME: &str = "nimbus:scheme";
    pub const TRANSMITTANCE: &str = "nimbus:transmittance";
    pub const CONTROL: &str = "nimbus:control";
    pub const OCTREE_DEPTH: &str = "nimbus:octreeDepth";
    pub const STRICT: &str = "nimbus:strict";
    pub const PREVIEW_NAME: &str = "nimbus:previewName";
    pub const LIGHT_GROUP: &str = "nimbus:lightGroup";
    pub const LIGHTS_INTERIOR: &str = "nimbus:lightsInterior";
    pub const HOLDOUT: &str = "nimbus:holdout";
    pub const FILL: &str = "nimbus:fill";
}

/// Why the embedded schema could not be registered. This is a build defect (the
/// files in `schemas/` are broken), never something a stage can cause, but it is
/// reported rather than panicking so a caller can print it.
#[derive(Debug, Clone, thiserror::Error)]
#[error("Nimbus schema registration failed: {0}")]
pub struct SchemaRegistrationError(String);

/// The registry every Nimbus stage is opened with: `openusd_schemas::ALL` plus
/// Nimbus' own family. Built once and shared.
pub fn registry() -> Result<Arc<SchemaRegistry>, SchemaRegistrationError> {
    static REGISTRY: OnceLock<Result<Arc<SchemaRegistry>, SchemaRegistrationError>> =
        OnceLock::new();
    REGISTRY.get_or_init(build_registry).clone()
}

fn build_registry() -> Result<Arc<SchemaRegistry>, SchemaRegistrationError> {
    let manifest_text = manifest_from_plug_info(PLUG_INFO)?;
    let manifest = sdf::Layer::from_bytes("nimbusSchemaManifest.usda", manifest_text.into_bytes())
        .map_err(|e| {
            SchemaRegistrationError(format!("manifest derived from plugInfo.json: {e}"))
        })?;
    let schematics = sdf::Layer::from_bytes("generatedSchema.usda", GENERATED_SCHEMA.as_bytes())
        .map_err(|e| SchemaRegistrationError(format!("generatedSchema.usda: {e}")))?;

    let builder = openusd_schemas::ALL
        .iter()
        .fold(SchemaRegistry::builder(), |builder, family| {
            builder.register(family)
        });
    builder
        .family(FamilySource {
            name: FAMILY,
            manifest: &manifest,
            schematics: &schematics,
        })
        .build()
        .map_err(|e| SchemaRegistrationError(e.to_string()))
}

/// Builds openusd's manifest layer (one `def` prim per schema identifier with
/// `schemaKind`, `bases`, `apiSchemaCanOnlyApplyTo`, `apiSchemaAutoApplyTo`) from
/// the `Types` of a C++ `plugInfo.json`.
pub fn manifest_from_plug_info(plug_info: &str) -> Result<String, SchemaRegistrationError> {
    let json: serde_json::Value = serde_json::from_str(&strip_plug_info_comments(plug_info))
        .map_err(|e| SchemaRegistrationError(format!("plugInfo.json: {e}")))?;
    let plugins = json
        .get("Plugins")
        .and_then(|p| p.as_array())
        .ok_or_else(|| SchemaRegistrationError("plugInfo.json: no Plugins array".into()))?;

    let mut out = String::from("#usda 1.0\n\n");
    for plugin in plugins {
        let Some(types) = plugin.pointer("/Info/Types").and_then(|t| t.as_object()) else {
            continue;
        };
        for (type_key, info) in types {
            write_manifest_prim(&mut out, type_key, info)?;
        }
    }
    Ok(out)
}

/// One schema's manifest prim. The schema identifier is the type's
/// `alias.UsdSchemaBase` (what `apiSchemas` lists), not its C++ type key.
fn write_manifest_prim(
    out: &mut String,
    type_key: &str,
    info: &serde_json::Value,
) -> Result<(), SchemaRegistrationError> {
    let missing = |what: &str| {
        SchemaRegistrationError(format!("plugInfo.json: type {type_key} has no {what}"))
    };
    let identifier = info
        .pointer("/alias/UsdSchemaBase")
        .and_then(|a| a.as_str())
        .ok_or_else(|| missing("alias.UsdSchemaBase"))?;
    let kind = info
        .get("schemaKind")
        .and_then(|k| k.as_str())
        .ok_or_else(|| missing("schemaKind"))?;
    // plugInfo names bases by C++ type (`UsdAPISchemaBase`); openusd's manifest
    // wants schema identifiers (`APISchemaBase`). Core USD types are the `Usd`
    // prefix plus the identifier.
    let bases: Vec<String> = string_list(info.get("bases"))
        .into_iter()
        .map(|b| b.strip_prefix("Usd").unwrap_or(&b).to_string())
        .collect();

    // `write!` to a String cannot fail; the results are ignored on purpose.
    let _ = writeln!(out, "def \"{identifier}\"\n{{");
    let _ = writeln!(out, "    uniform token schemaKind = \"{kind}\"");
    write_token_array(out, "bases", &bases);
    write_token_array(
        out,
        "apiSchemaCanOnlyApplyTo",
        &string_list(info.get("apiSchemaCanOnlyApplyTo")),
    );
    write_token_array(
        out,
        "apiSchemaAutoApplyTo",
        &string_list(info.get("apiSchemaAutoApplyTo")),
    );
    out.push_str("}\n\n");
    Ok(())
}

fn write_token_array(out: &mut String, name: &str, items: &[String]) {
    if items.is_empty() {
        return;
    }
    let quoted: Vec<String> = items.iter().map(|i| format!("\"{i}\"")).collect();
    let _ = writeln!(out, "    uniform token[] {name} = [{}]", quoted.join(", "));
}

fn string_list(value: Option<&serde_json::Value>) -> Vec<String> {
    value
        .and_then(|v| v.as_array())
        .map(|a| {
            a.iter()
                .filter_map(|s| s.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default()
}

/// C++ plugInfo files allow `#` line comments, which JSON does not.
fn strip_plug_info_comments(text: &str) -> String {
    text.lines()
        .filter(|line| !line.trim_start().starts_with('#'))
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use openusd::tf::Token;

    #[test]
    fn registry_knows_nimbus_api_schemas() {
        let registry = registry().expect("embedded schema registers");
        for api in [VOLUME_API, RENDER_SETTINGS_API, HOLDOUT_API] {
            let info = registry
                .schema_info(&Token::from(api))
                .expect("schema registered");
            assert!(info.is_applied_api());
            assert!(registry.api_prim_definition(&Token::from(api)).is_some());
        }
    }
}

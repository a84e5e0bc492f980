//! Path splits and light groups: RenderVars that split the beauty by where its light
//! came from, so a compositor can re-light a volume pass.
//!
//! A split layer gathers the contributions of some *sources* (UsdLux lights, and
//! emissive volumes) that reached the camera after some number of *scattering events*.
//! Every contribution the integrator adds to the beauty is also added to each layer
//! whose filter it passes, so layers cost no extra tracking, and layers that partition
//! the paths (light groups covering every source; `emission` + `direct` + `indirect`)
//! sum to the beauty within float rounding.
//!
//! RenderVars name layers with a light path expression (`sourceType = "lpe"`), in the
//! dialect Karma and RenderMan accept for volumes, restricted to what a volume-only
//! renderer has (camera `C`, volume scattering `V`, lights `L`, emissive objects `O`):
//!
//! | sourceName        | gathers                                                    |
//! |-------------------|------------------------------------------------------------|
//! | `C.*`             | everything (the beauty)                                    |
//! | `C[LO]`           | lights and volume emission seen without scattering         |
//! | `CV[LO]`          | single scattering (and emission scattered once)            |
//! | `CV.+[LO]`        | multiple scattering (two or more events)                   |
//! | `C.*<L.'key'>`    | the lights of light group `key`, at any number of events   |
//! | `C.*<O.'key'>`    | the emission of the volumes of light group `key`           |
//! | `C.*<[LO].'key'>` | both                                                       |
//!
//! (`L` or `O` alone instead of `[LO]` keeps only lights or only emission; `C`, `CV`,
//! `CV.+`, `C.+` and `C.*` are the event counts 0, 1, ≥ 2, ≥ 1 and any.) A group
//! name matches the sources whose `nimbus:lightGroup` it is, and the one whose prim
//! path it is, so `C.*<L.'/World/key'>` is a per-light AOV whatever the light's group. Plain names (`sourceType = "raw"` or
//! `--aovs`) are shorthands: `emission` = `C[LO]`, `direct` = `CV[LO]`, `indirect` =
//! `CV.+[LO]`, `lightgroup:key` = `C.*<[LO].'key'>`.

use crate::scene::Emitter;

/// At most this many split layers in one render (one bit each in a source's mask).
pub const MAX_LAYERS: usize = 64;

/// How many scattering events a contribution passed through between the camera and
/// its source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Events {
    Any,
    Zero,
    One,
    TwoOrMore,
    OneOrMore,
}

impl Events {
    fn admits(self, events: u32) -> bool {
        match self {
            Events::Any => true,
            Events::Zero => events == 0,
            Events::One => events == 1,
            Events::TwoOrMore => events >= 2,
            Events::OneOrMore => events >= 1,
        }
    }
}

/// One split layer: an RGB image of the contributions that pass its filter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SplitLayer {
    /// The EXR layer name (channels `name.R`, `name.G`, `name.B`).
    pub name: String,
    pub events: Events,
    /// Whether it gathers UsdLux lights.
    pub lights: bool,
    /// Whether it gathers volume emission.
    pub emission: bool,
    /// Only the sources of this light group (`None`: every source).
    pub group: Option<String>,
}

impl SplitLayer {
    /// The layer a RenderVar's `sourceName` of `source_type` names, or an error saying
    /// what is accepted. `name` is the layer name to give it.
    pub fn parse(name: &str, source_name: &str, source_type: &str) -> Result<SplitLayer, String> {
        let text: String = source_name.chars().filter(|c| !c.is_whitespace()).collect();
        let layer = |events, lights, emission, group: Option<&str>| SplitLayer {
            name: name.to_string(),
            events,
            lights,
            emission,
            group: group.map(str::to_string),
        };
        let shorthand = match text.as_str() {
            "emission" => Some(layer(Events::Zero, true, true, None)),
            "direct" => Some(layer(Events::One, true, true, None)),
            "indirect" => Some(layer(Events::TwoOrMore, true, true, None)),
            _ => text
                .strip_prefix("lightgroup:")
                .filter(|g| !g.is_empty())
                .map(|g| layer(Events::Any, true, true, Some(g))),
        };
        match (source_type, shorthand) {
            ("lpe", _) => parse_lpe(text.strip_prefix("lpe:").unwrap_or(&text))
                .map(|(events, lights, emission, group)| {
                    layer(events, lights, emission, group.as_deref())
                })
                .ok_or_else(|| {
                    format!(
                        "light path expression \"{source_name}\" is not one Nimbus splits; accepted: \
                         C.*, C[LO], CV[LO], CV.+[LO], C.*<L.'group'> (L or O for lights or emission only; \
                         C, CV, CV.+, C.+, C.* for 0, 1, 2 or more, 1 or more, any scattering events)"
                    )
                }),
            (_, Some(l)) => Ok(l),
            _ => Err(format!("\"{source_name}\" is not a split AOV")),
        }
    }

    /// Whether this layer gathers `source` (of kind light or emission) after `events`
    /// scattering events.
    fn gathers(&self, source: &Emitter, is_light: bool, events: u32) -> bool {
        let kind = if is_light { self.lights } else { self.emission };
        kind && self.events.admits(events)
            && self.group.as_deref().is_none_or(|g| in_group(source, g))
    }
}

/// Whether `source` belongs to light group `group`: `group` is its
/// `nimbus:lightGroup`, or its prim path (so every light has a per-light AOV).
pub fn in_group(source: &Emitter, group: &str) -> bool {
    source.light_group == Some(group) || source.prim_path == group
}

/// `(events, lights, emission, group)` of a light path expression in the dialect of
/// the module comment, or `None`.
fn parse_lpe(lpe: &str) -> Option<(Events, bool, bool, Option<String>)> {
    let rest = lpe.strip_prefix('C')?;
    if rest == ".*" {
        return Some((Events::Any, true, true, None));
    }
    // The source is the expression's tail: `L`, `O`, `[LO]`, or `<X.'group'>`.
    let (middle, lights, emission, group) = if let Some(open) = rest.rfind('<') {
        let inner = rest[open..].strip_prefix('<')?.strip_suffix('>')?;
        let (kind, quoted) = inner.split_once('.')?;
        let group = quoted.strip_prefix('\'')?.strip_suffix('\'')?;
        if group.is_empty() || group.contains('\'') {
            return None;
        }
        let (l, o) = source_kind(kind)?;
        (&rest[..open], l, o, Some(group.to_string()))
    } else {
        let split = ["[LO]", "[OL]", "L", "O"]
            .iter()
            .find_map(|k| rest.strip_suffix(k).map(|m| (m, *k)))?;
        let (l, o) = source_kind(split.1)?;
        (split.0, l, o, None)
    };
    let events = match middle {
        "" => Events::Zero,
        "V" => Events::One,
        "V.+" | "VV+" | "V{2,}" | "VV.*" => Events::TwoOrMore,
        ".+" | "V+" | "V.*" => Events::OneOrMore,
        ".*" | "V*" => Events::Any,
        _ => return None,
    };
    Some((events, lights, emission, group))
}

fn source_kind(kind: &str) -> Option<(bool, bool)> {
    match kind {
        "L" => Some((true, false)),
        "O" => Some((false, true)),
        "[LO]" | "[OL]" => Some((true, true)),
        _ => None,
    }
}

/// The layers of a render and, per source and number of events, which layers a
/// contribution feeds: what the integrator consults per contribution.
#[derive(Clone, Debug, Default)]
pub struct SplitMap {
    pub layers: Vec<SplitLayer>,
    /// Per source (lights in [`crate::scene::Scene::lights`] order, then one per
    /// medium), a bit mask of layers for 0, 1 and ≥ 2 scattering events.
    masks: Vec<[u64; 3]>,
    /// Lights come first among the sources; medium `i` is source `lights + i`.
    lights: usize,
}

impl SplitMap {
    /// The map of `layers` over the scene's `lights` and `volumes` (emitters whose
    /// emission is their medium's). A group that names no source is an error naming
    /// the layer: a typo would otherwise give a silently black AOV.
    pub fn new(
        layers: Vec<SplitLayer>,
        lights: &[Emitter],
        volumes: &[Emitter],
    ) -> Result<SplitMap, String> {
        if layers.len() > MAX_LAYERS {
            return Err(format!(
                "{} split AOVs requested; Nimbus writes at most {MAX_LAYERS} per render",
                layers.len()
            ));
        }
        for l in &layers {
            if let Some(g) = &l.group {
                let hit = (l.lights && lights.iter().any(|s| in_group(s, g)))
                    || (l.emission && volumes.iter().any(|s| in_group(s, g)));
                if !hit {
                    return Err(format!(
                        "AOV {}: light group '{g}' matches no {} (a group is a nimbus:lightGroup, or a prim path)",
                        l.name,
                        match (l.lights, l.emission) {
                            (true, false) => "light",
                            (false, true) => "volume",
                            _ => "light or volume",
                        }
                    ));
                }
            }
        }
        let mask = |source: &Emitter, is_light: bool| -> [u64; 3] {
            std::array::from_fn(|events| {
                layers
                    .iter()
                    .enumerate()
                    .filter(|(_, l)| l.gathers(source, is_light, events as u32))
                    .fold(0u64, |m, (i, _)| m | 1 << i)
            })
        };
        let masks = lights
            .iter()
            .map(|s| mask(s, true))
            .chain(volumes.iter().map(|s| mask(s, false)))
            .collect();
        Ok(SplitMap {
            layers,
            masks,
            lights: lights.len(),
        })
    }

    pub fn is_empty(&self) -> bool {
        self.layers.is_empty()
    }

    pub fn len(&self) -> usize {
        self.layers.len()
    }

    /// The source index of medium `i`'s emission.
    pub fn emission_source(&self, medium: usize) -> usize {
        self.lights + medium
    }

    /// Adds `v`, a contribution of `source` after `events` scattering events, to the
    /// layers it feeds.
    #[inline]
    pub fn add(&self, layers: &mut [[f64; 3]], source: usize, events: u32, v: [f64; 3]) {
        // A source with no mask (lights built by hand) feeds no layer.
        let Some(masks) = self.masks.get(source) else {
            return;
        };
        let mut mask = masks[events.min(2) as usize];
        while mask != 0 {
            let i = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            for c in 0..3 {
                layers[i][c] += v[c];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn e<'a>(path: &'a str, group: Option<&'a str>) -> Emitter<'a> {
        Emitter {
            prim_path: path,
            light_group: group,
        }
    }

    #[test]
    fn parses_the_documented_expressions() {
        let p =
            |s| SplitLayer::parse("x", s, "lpe").map(|l| (l.events, l.lights, l.emission, l.group));
        assert_eq!(p("C.*"), Ok((Events::Any, true, true, None)));
        assert_eq!(p("C[LO]"), Ok((Events::Zero, true, true, None)));
        assert_eq!(p("lpe:CV[LO]"), Ok((Events::One, true, true, None)));
        assert_eq!(p("CV.+[LO]"), Ok((Events::TwoOrMore, true, true, None)));
        assert_eq!(p("CVL"), Ok((Events::One, true, false, None)));
        assert_eq!(p("C.+O"), Ok((Events::OneOrMore, false, true, None)));
        assert_eq!(
            p("C.*<L.'key'>"),
            Ok((Events::Any, true, false, Some("key".into())))
        );
        assert_eq!(
            p("C V <[LO].'fire'>"),
            Ok((Events::One, true, true, Some("fire".into())))
        );
        for bad in ["", "C", "CD L", "C.*<L.''>", "C.*<L.key>", "CR L", "X.*"] {
            assert!(p(bad).is_err(), "{bad:?} should not parse");
        }
        let raw = |s| SplitLayer::parse("x", s, "raw").map(|l| (l.events, l.group));
        assert_eq!(raw("direct"), Ok((Events::One, None)));
        assert_eq!(raw("lightgroup:key"), Ok((Events::Any, Some("key".into()))));
        assert!(raw("lightgroup:").is_err());
        assert!(raw("C.*").is_err());
    }

    #[test]
    fn masks_follow_groups_and_event_counts() {
        let layers = [
            "C[LO]",
            "CV[LO]",
            "CV.+[LO]",
            "C.*<L.'key'>",
            "C.*<O.'/fire'>",
        ]
        .iter()
        .map(|s| SplitLayer::parse(s, s, "lpe").unwrap())
        .collect();
        let lights = [e("/sun", Some("key")), e("/sky", None)];
        let volumes = [e("/fire", None)];
        let map = SplitMap::new(layers, &lights, &volumes).unwrap();
        let mut acc = [[0.0; 3]; 5];
        map.add(&mut acc, 0, 1, [1.0; 3]); // sun, single scattering
        map.add(&mut acc, 1, 0, [2.0; 3]); // sky seen directly
        map.add(&mut acc, 2, 5, [4.0; 3]); // fire, scattered 5 times
        let r: Vec<f64> = acc.iter().map(|v| v[0]).collect();
        assert_eq!(r, vec![2.0, 1.0, 4.0, 1.0, 4.0]);
    }

    #[test]
    fn a_group_of_nothing_is_an_error() {
        let layers = vec![SplitLayer::parse("lg", "C.*<L.'rim'>", "lpe").unwrap()];
        let err = SplitMap::new(layers, &[e("/sun", Some("key"))], &[]).unwrap_err();
        assert!(err.contains("lg") && err.contains("'rim'"), "{err}");
    }
}

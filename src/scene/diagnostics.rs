//! What a stage asks for that Nimbus does not honour (a light filter, a portal light, a
//! motion-blurred transform, a shader it cannot read …), or reads in a way its author
//! may not expect (a negative intensity): collected while the stage is loaded, so a
//! render never differs from the stage without a word.
//!
//! Each warning names the prim and, where there is one, the attribute or relationship.
//! `render` prints them (one line per kind: a stage with a thousand light filters gets
//! one line, not a thousand), `info` lists them, the stats JSON records every one, and
//! `--strict` (or `nimbus:strict` on the RenderSettings prim) turns them into an error.

use serde::Serialize;

/// One thing on the stage that the render does not show as authored.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct StageWarning {
    /// What kind of thing it is, the key warnings are grouped by ("light filter",
    /// "PortalLight", "motion blur", …).
    pub kind: String,
    /// The prim it is about.
    pub prim: String,
    /// The attribute or relationship at fault, when one is.
    pub attribute: Option<String>,
    /// What Nimbus does instead ("ignored: the light is unfiltered").
    pub message: String,
}

impl StageWarning {
    /// `PRIM.ATTRIBUTE` (or `PRIM` when no attribute is named).
    pub fn location(&self) -> String {
        match &self.attribute {
            Some(a) => format!("{}.{a}", self.prim),
            None => self.prim.clone(),
        }
    }
}

/// The warnings of one stage, in the order they were found.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(transparent)]
pub struct Diagnostics {
    warnings: Vec<StageWarning>,
}

/// How many other places a grouped warning names before it only counts them.
const LISTED: usize = 3;

impl Diagnostics {
    /// Records that `prim` (its `attribute`, if given) is not rendered as authored:
    /// `message` says what Nimbus does instead. The same warning twice is kept once.
    pub fn warn(
        &mut self,
        kind: impl Into<String>,
        prim: impl Into<String>,
        attribute: Option<&str>,
        message: impl Into<String>,
    ) {
        let w = StageWarning {
            kind: kind.into(),
            prim: prim.into(),
            attribute: attribute.map(str::to_string),
            message: message.into(),
        };
        if !self.warnings.contains(&w) {
            self.warnings.push(w);
        }
    }

    pub fn is_empty(&self) -> bool {
        self.warnings.is_empty()
    }

    pub fn len(&self) -> usize {
        self.warnings.len()
    }

    pub fn iter(&self) -> impl Iterator<Item = &StageWarning> {
        self.warnings.iter()
    }

    /// Appends `other`'s warnings (duplicates kept once).
    pub fn extend(&mut self, other: Diagnostics) {
        for w in other.warnings {
            if !self.warnings.contains(&w) {
                self.warnings.push(w);
            }
        }
    }

    /// One line per kind, in the order kinds were first met: the first warning's
    /// location and message, then the other places of that kind (a few named, the rest
    /// counted).
    pub fn lines(&self) -> Vec<String> {
        let mut kinds: Vec<&str> = Vec::new();
        for w in &self.warnings {
            if !kinds.contains(&w.kind.as_str()) {
                kinds.push(&w.kind);
            }
        }
        kinds
            .into_iter()
            .map(|kind| {
                let mut of_kind = self.warnings.iter().filter(|w| w.kind == kind);
                let first = of_kind.next().expect("a kind has a warning");
                let others: Vec<String> = of_kind.map(StageWarning::location).collect();
                let mut line = format!("{}: {}", first.location(), first.message);
                if !others.is_empty() {
                    let named = others[..others.len().min(LISTED)].join(", ");
                    let rest = others.len().saturating_sub(LISTED);
                    line += &format!(" (the same for {named}");
                    if rest > 0 {
                        line += &format!(" and {rest} more");
                    }
                    line += ")";
                }
                line
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_per_kind_naming_the_first_and_counting_the_rest() {
        let mut d = Diagnostics::default();
        for i in 0..6 {
            d.warn(
                "light filter",
                format!("/L{i}"),
                Some("light:filters"),
                "ignored",
            );
        }
        d.warn("PortalLight", "/P", None, "not supported: ignored");
        d.warn("PortalLight", "/P", None, "not supported: ignored");
        assert_eq!(d.len(), 7, "the repeated warning is kept once");
        assert_eq!(
            d.lines(),
            vec![
                "/L0.light:filters: ignored (the same for /L1.light:filters, /L2.light:filters, /L3.light:filters and 2 more)".to_string(),
                "/P: not supported: ignored".to_string(),
            ]
        );
    }
}

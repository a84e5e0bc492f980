//! Clap value parsers for the library's named options ([`Choice`]): the library keeps no
//! CLI derives, the names and help lines come from it.

use crate::track::select::Choice;
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

/// A parser accepting the names of `K`'s options (help lists them with their lines).
pub fn parser<K: Choice + Send + Sync>() -> impl TypedValueParser<Value = K> {
    PossibleValuesParser::new(possible_values::<K>())
        .map(|name| K::from_name(&name).expect("clap accepted only the option names"))
}

/// `K`'s options as clap possible values.
pub fn possible_values<K: Choice>() -> Vec<PossibleValue> {
    K::ALL
        .iter()
        .map(|k| PossibleValue::new(k.name()).help(k.help()))
        .collect()
}

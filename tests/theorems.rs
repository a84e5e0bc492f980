//! The supplement's Theorems 1 and 2 as property tests over random coefficients and
//! random throughput histories.

use nimbus::track::scheme::{choose, probabilities, Coefficients, HistAvg, Max, SchemeOptions};
use proptest::prelude::*;

/// Coefficients of a bounding-majorant collision: μa, μs ≥ 0 per channel, μ̄ ≥ max μt
/// (by a factor `slack` ≥ 1), μn = μ̄ − μt ≥ 0.
fn coefficients(a: [f32; 3], s: [f32; 3], slack: f32) -> (Coefficients, f32) {
    let t = [a[0] + s[0], a[1] + s[1], a[2] + s[2]];
    let mu_bar = t[0].max(t[1]).max(t[2]) * slack;
    (
        Coefficients {
            mu_a: a,
            mu_s: s,
            mu_n: t.map(|v| mu_bar - v),
        },
        mu_bar,
    )
}

fn triple() -> impl Strategy<Value = [f32; 3]> {
    prop::array::uniform3(prop_oneof![Just(0.0f32), 1e-4f32..1.0, 1.0f32..100.0])
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20_000, ..ProptestConfig::default() })]

    /// Theorem 1: with the (history-free) max scheme, every local collision weight is at
    /// most 3, and at most 2 when absorption events are not sampled.
    #[test]
    fn theorem1_max_scheme_weights_bounded(a in triple(), s in triple(), slack in 1.0f32..4.0, u in 0.0f32..1.0) {
        let (k, mu_bar) = coefficients(a, s, slack);
        prop_assume!(mu_bar > 0.0);
        for (opts, bound) in [
            (SchemeOptions::default(), 3.0f32),
            (SchemeOptions { no_absorption_events: true, ..SchemeOptions::default() }, 2.0),
        ] {
            let p = probabilities::<Max>(&k, mu_bar, [1.0; 3], opts);
            let (_, w) = choose(&k, mu_bar, p, u);
            for ch in 0..3 {
                prop_assert!(w[ch] <= bound * (1.0 + 1e-5), "w = {:?}, bound {}", w, bound);
            }
        }
    }

    /// Theorem 2: with history-aware avg and a bounding majorant, Σλ w(λ) = 3 after every
    /// collision, so no channel exceeds 3, over random histories of 1–50 collisions.
    #[test]
    fn theorem2_hist_avg_keeps_channel_sum(
        steps in prop::collection::vec((triple(), triple(), 1.0f32..4.0, 0.0f32..1.0), 1..50)
    ) {
        let mut w = [1f32; 3];
        for (a, s, slack, u) in steps {
            let (k, mu_bar) = coefficients(a, s, slack);
            if !(mu_bar > 0.0) {
                continue;
            }
            let p = probabilities::<HistAvg>(&k, mu_bar, w, SchemeOptions::default());
            let (_, lw) = choose(&k, mu_bar, p, u);
            for ch in 0..3 {
                w[ch] *= lw[ch];
            }
            let sum = w[0] + w[1] + w[2];
            prop_assert!((sum - 3.0).abs() < 1e-3, "sum {} w {:?}", sum, w);
            prop_assert!(w.iter().all(|&x| x <= 3.0 + 1e-3));
        }
    }
}

//! One local light chosen per scattering vertex where a stage has many (issue 44).
//!
//! Next-event estimation samples every local light at every vertex: a shadow ray each,
//! the right trade for a few lights. With dozens (embers in smoke, a string of lamps in
//! fog) the shadow rays are most of a path's cost while most lights, far away or
//! behind thick smoke, add little. Past [`MANY_LIGHTS`] local lights, a vertex `p`
//! samples one light ℓ, chosen with probability
//!
//! ```text
//! P_ℓ(p) = w_ℓ(p) / Σ_k w_k(p),   w_ℓ(p) = Φ_ℓ / max(d_ℓ(p)², r_ℓ²)
//! ```
//!
//! (its power over its squared distance, never nearer than its radius: the weights of
//! [`crate::render::guiding`]'s lobes), and its estimate is divided by P_ℓ(p). Every
//! light with power has P_ℓ > 0 everywhere, so the sum over lights stays unbiased; the
//! equiangular MIS weights are per light and unchanged.
//!
//! Up to [`TREE_LIGHTS`] lights that is a linear pass over them per vertex. Past it a
//! [`LightTree`] draws the light: each inner node chooses between its two children by
//! an estimate of their clusters' summed weights, and a leaf among its few lights by
//! their exact weights; the light's probability is the product of the choices, exact
//! for the light drawn whatever the estimate (docs/trackers.md, "Many local lights").

use crate::render::equiangular::LocalLight;
use crate::render::guiding::importance;
use glam::DVec3;

/// Stages with more local lights than this choose one per vertex; up to it, every
/// light is sampled at every vertex (and such renders are unchanged).
pub const MANY_LIGHTS: usize = 4;

/// Past this many local lights the choice descends a [`LightTree`] instead of weighing
/// every light (docs/trackers.md, "At hundreds and thousands of lights").
pub const TREE_LIGHTS: usize = 64;

/// A tree's leaf holds at most this many lights, chosen among by their exact weights:
/// the cluster estimate is coarsest at the bottom, where a vertex often sits among the
/// cluster's lights.
const LEAF_LIGHTS: usize = 8;

/// The local lights as the choice sees them, in [`crate::render::lights::Lights::locals`]'
/// order (the index next-event estimation counts lights by).
#[derive(Clone, Debug)]
pub struct LightChoice {
    lights: Vec<(DVec3, f64, f64)>,
    /// Past [`TREE_LIGHTS`] lights with power.
    tree: Option<LightTree>,
}

impl LightChoice {
    /// `None` for [`MANY_LIGHTS`] local lights or fewer: every light is sampled.
    pub fn new(locals: &[LocalLight]) -> Option<LightChoice> {
        (locals.len() > MANY_LIGHTS).then(|| {
            let lights: Vec<_> = locals
                .iter()
                .map(|l| (l.center, l.power.max(0.0), l.radius * l.radius))
                .collect();
            LightChoice {
                tree: LightTree::new(&lights),
                lights,
            }
        })
    }

    /// Whether the choice descends a [`LightTree`] (past [`TREE_LIGHTS`] lights with
    /// power) rather than weighing every light.
    pub fn walks_a_tree(&self) -> bool {
        self.tree.is_some()
    }

    /// The light vertex `p` samples, drawn with the uniform `u`, and its probability;
    /// `None` where no light has power.
    pub fn pick(&self, p: DVec3, u: f64) -> Option<(usize, f64)> {
        match &self.tree {
            Some(tree) => tree.pick(&self.lights, p, u),
            None => pick_among(&self.lights, 0..self.lights.len() as u32, |k| k, p, u),
        }
    }
}

/// The light's weight at `p`: the lobes' importance.
#[inline]
fn weight(&(c, power, r2): &(DVec3, f64, f64), p: DVec3) -> f64 {
    importance(power, (c - p).length_squared(), r2)
}

/// One of the lights `index(i)` for `i` in `range`, drawn with `u` by its exact weight
/// at `p`, and its probability among them; `None` where none has power.
#[inline]
fn pick_among(
    lights: &[(DVec3, f64, f64)],
    range: std::ops::Range<u32>,
    index: impl Fn(u32) -> u32,
    p: DVec3,
    u: f64,
) -> Option<(usize, f64)> {
    let total: f64 = range
        .clone()
        .map(|i| weight(&lights[index(i) as usize], p))
        .sum();
    if !(total > 0.0 && total.is_finite()) {
        return None;
    }
    let target = u * total;
    let mut acc = 0.0;
    let mut last = None;
    for i in range {
        let k = index(i) as usize;
        let w = weight(&lights[k], p);
        if w <= 0.0 {
            continue;
        }
        acc += w;
        last = Some((k, w / total));
        if acc > target {
            break;
        }
    }
    last
}

/// A binary tree over the lights with power, built once per render: a node splits its
/// lights at the median of their centres along the longest axis of their box, down to
/// leaves of at most [`LEAF_LIGHTS`].
///
/// A node is a cluster, weighed at `p` by its summed power Φ over the squared distances
/// to the nearest and the farthest point of its centres' box, averaged:
/// `Φ/2 · (1 / max(d_min², r²) + 1 / max(d_max², r²))`, `r²` the least squared radius
/// among its lights. The first bounds the sum of its lights' weights above (every light
/// as near as the box allows), the second below, and far off both are Φ / d², that sum.
/// Of four estimates measured on 1,000 lights in smoke (docs/trackers.md) this one had
/// the least variance, less than the power-weighted centroid with or without the
/// lights' spread.
#[derive(Clone, Debug)]
pub struct LightTree {
    /// The root is node 0.
    nodes: Vec<Node>,
    /// The lights with power, leaf by leaf: a leaf's lights are a range of it.
    order: Vec<u32>,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    power: f64,
    /// The box of the cluster's lights' centres.
    lo: DVec3,
    hi: DVec3,
    min_radius2: f64,
    /// An inner node: its children; a leaf: its range of `order`.
    a: u32,
    b: u32,
    leaf: bool,
}

impl Node {
    #[inline]
    fn weight(&self, p: DVec3) -> f64 {
        let near = (self.lo - p).max(p - self.hi).max(DVec3::ZERO);
        let far = (p - self.lo).abs().max((self.hi - p).abs());
        0.5 * (importance(self.power, near.length_squared(), self.min_radius2)
            + importance(self.power, far.length_squared(), self.min_radius2))
    }
}

impl LightTree {
    /// `None` for [`TREE_LIGHTS`] lights with power or fewer.
    fn new(lights: &[(DVec3, f64, f64)]) -> Option<LightTree> {
        let mut order: Vec<u32> = (0..lights.len() as u32)
            .filter(|&k| lights[k as usize].1 > 0.0)
            .collect();
        if order.len() <= TREE_LIGHTS {
            return None;
        }
        let mut nodes = Vec::with_capacity(2 * order.len() / LEAF_LIGHTS + 1);
        Self::build(lights, &mut order, 0, &mut nodes);
        Some(LightTree { nodes, order })
    }

    /// Appends the node over `order` (which starts at `offset` in the whole order) and
    /// its subtree to `nodes`; returns its index.
    fn build(
        lights: &[(DVec3, f64, f64)],
        order: &mut [u32],
        offset: u32,
        nodes: &mut Vec<Node>,
    ) -> u32 {
        let of = |k: &u32| lights[*k as usize];
        let (lo, hi) = order.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), k| (lo.min(of(k).0), hi.max(of(k).0)),
        );
        let at = nodes.len() as u32;
        let leaf = order.len() <= LEAF_LIGHTS;
        nodes.push(Node {
            power: order.iter().map(|k| of(k).1).sum(),
            lo,
            hi,
            min_radius2: order.iter().map(|k| of(k).2).fold(f64::INFINITY, f64::min),
            a: offset,
            b: offset + order.len() as u32,
            leaf,
        });
        if leaf {
            return at;
        }
        let extent = hi - lo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        // Ties by index: the same tree whatever the sort's internals.
        order.sort_unstable_by(|a, b| of(a).0[axis].total_cmp(&of(b).0[axis]).then(a.cmp(b)));
        let mid = order.len() / 2;
        let (left, right) = order.split_at_mut(mid);
        let l = Self::build(lights, left, offset, nodes);
        let r = Self::build(lights, right, offset + mid as u32, nodes);
        nodes[at as usize].a = l;
        nodes[at as usize].b = r;
        at
    }

    /// Descends from the root, choosing each node's child by their clusters' weights at
    /// `p` with `u` (rescaled after each choice), then a light of the leaf by the
    /// lights' own; the light and the product of the choices' probabilities.
    fn pick(&self, lights: &[(DVec3, f64, f64)], p: DVec3, mut u: f64) -> Option<(usize, f64)> {
        let mut node = &self.nodes[0];
        let mut prob = 1.0;
        while !node.leaf {
            let (l, r) = (&self.nodes[node.a as usize], &self.nodes[node.b as usize]);
            let (wl, wr) = (l.weight(p), r.weight(p));
            let total = wl + wr;
            if !(total > 0.0 && total.is_finite()) {
                return None;
            }
            let pl = wl / total;
            if u < pl {
                u = (u / pl).min(ONE_MINUS_EPSILON);
                prob *= pl;
                node = l;
            } else {
                u = ((u - pl) / (1.0 - pl)).clamp(0.0, ONE_MINUS_EPSILON);
                prob *= 1.0 - pl;
                node = r;
            }
        }
        let (k, pk) = pick_among(lights, node.a..node.b, |i| self.order[i as usize], p, u)?;
        (prob * pk > 0.0).then_some((k, prob * pk))
    }
}

/// The largest f64 below 1: a rescaled uniform stays in [0, 1).
const ONE_MINUS_EPSILON: f64 = 1.0 - f64::EPSILON / 2.0;

#[cfg(test)]
mod tests {
    use super::*;

    fn light(x: f64, power: f64) -> LocalLight {
        LocalLight {
            center: DVec3::new(x, 0.0, 0.0),
            power,
            radius: 0.1,
            cone: None,
            chord: None,
        }
    }

    /// Past [`TREE_LIGHTS`] the tree draws each light with the probability it reports:
    /// 300 lights at pseudo-random places, powers and radii (Pcg64, seed 44), one without
    /// power, at three vertices (beside a light, at the cluster's edge, far off). The
    /// tree maps u to the lights monotonically, each light an interval of length P, so
    /// over N = 600,000 stratified draws each light's count is P·N within one draw; the
    /// probabilities of the lights drawn sum to 1 less at most what lights with P < 1/N
    /// leave unseen; the powerless light is never drawn; beside a light, that light is
    /// drawn more often than any light 5 away.
    #[test]
    fn the_tree_draws_lights_with_the_probabilities_it_reports() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(44);
        let mut next = || rng.gen::<f64>();
        let n_lights = 300;
        let lights: Vec<LocalLight> = (0..n_lights)
            .map(|i| LocalLight {
                center: DVec3::new(next() * 20.0 - 10.0, next() * 20.0 - 10.0, next() * 5.0),
                power: if i == 7 { 0.0 } else { 1.0 + 100.0 * next() },
                radius: 0.05 + 0.2 * next(),
                cone: None,
                chord: None,
            })
            .collect();
        let choice = LightChoice::new(&lights).unwrap();
        assert!(choice.tree.is_some());
        let near = lights[3].center + DVec3::new(0.3, 0.0, 0.0);
        for p in [
            near,
            DVec3::new(12.0, 0.0, 2.0),
            DVec3::new(0.0, 300.0, 0.0),
        ] {
            let n = 600_000;
            let mut counts = vec![0usize; n_lights];
            let mut prob = vec![0.0; n_lights];
            for i in 0..n {
                let (k, pk) = choice.pick(p, (i as f64 + 0.5) / n as f64).unwrap();
                counts[k] += 1;
                assert!(
                    prob[k] == 0.0 || prob[k] == pk,
                    "light {k}: {} then {pk}",
                    prob[k]
                );
                prob[k] = pk;
            }
            assert_eq!(counts[7], 0);
            let unseen = (0..n_lights).filter(|&k| k != 7 && counts[k] == 0).count();
            let sum: f64 = prob.iter().sum();
            assert!(
                sum <= 1.0 + 1e-9 && sum >= 1.0 - unseen as f64 / n as f64 - 1e-9,
                "{p}: probabilities sum to {sum}, {unseen} lights unseen"
            );
            for k in 0..n_lights {
                let expected = prob[k] * n as f64;
                assert!(
                    (counts[k] as f64 - expected).abs() <= 1.0 + 1e-9 * n as f64,
                    "{p}, light {k}: {} drawn, {expected} expected",
                    counts[k]
                );
            }
            if p == near {
                let far_max = (0..n_lights)
                    .filter(|&k| (lights[k].center - p).length() > 5.0)
                    .map(|k| prob[k])
                    .fold(0.0, f64::max);
                assert!(prob[3] > far_max, "near {} far {far_max}", prob[3]);
            }
        }
    }

    #[test]
    fn few_lights_are_all_sampled() {
        let four: Vec<_> = (0..MANY_LIGHTS).map(|i| light(i as f64, 1.0)).collect();
        assert!(LightChoice::new(&four).is_none());
    }

    /// Every light is picked with the probability `pick` reports: the picks' counts
    /// over 200,000 draws (stratified u, so exact up to one draw per light) against
    /// P·N, and the probabilities sum to 1; a light without power is never picked.
    #[test]
    fn picks_follow_their_probabilities() {
        let lights = [
            light(0.0, 1.0),
            light(1.0, 0.0),
            light(2.0, 4.0),
            light(5.0, 20.0),
            light(0.05, 0.5),
            light(-3.0, 9.0),
        ];
        let choice = LightChoice::new(&lights).unwrap();
        let p = DVec3::new(0.5, 0.2, 0.0);
        let n = 200_000;
        let mut counts = [0usize; 6];
        let mut prob = [0.0; 6];
        for i in 0..n {
            let (k, pk) = choice.pick(p, (i as f64 + 0.5) / n as f64).unwrap();
            counts[k] += 1;
            prob[k] = pk;
        }
        assert_eq!(counts[1], 0);
        assert!((prob.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{prob:?}");
        for k in 0..6 {
            let expected = prob[k] * n as f64;
            assert!(
                (counts[k] as f64 - expected).abs() <= 1.0,
                "{k}: {counts:?} {prob:?}"
            );
        }
    }
}

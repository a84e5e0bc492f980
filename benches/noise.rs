//! Criterion benchmarks of the procedural noises a density graph evaluates per lookup:
//! Blender's Noise Texture (Fac, and Fac with Color) and MaterialX's `fractal3d`, over
//! 4,096 random points in [-3, 3)^4 per iteration. Run with
//! `cargo bench --bench noise --ignore-rust-version`; against the commit before with
//! criterion's baselines (`-- --save-baseline before` there, `-- --baseline before` here).
//! docs/shaders.md ("Cost") has the measured numbers.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use nimbus::shader::materialx_noise::fractal_noise_3d;
use nimbus::shader::noise::{Dimensions, NoiseTexture};
use rand::{Rng, SeedableRng};
use std::hint::black_box;

const POINTS: usize = 4096;

fn points() -> Vec<[f32; 4]> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(47);
    (0..POINTS)
        .map(|_| std::array::from_fn(|_| rng.gen_range(-3.0f32..3.0)))
        .collect()
}

fn blender_noise(c: &mut Criterion) {
    let pts = points();
    let mut g = c.benchmark_group("noise");
    g.throughput(Throughput::Elements(POINTS as u64));
    let defaults = NoiseTexture::default();
    let issue = NoiseTexture {
        scale: 2.0,
        detail: 4.0,
        ..NoiseTexture::default()
    };
    let four_d = NoiseTexture {
        dimensions: Dimensions::D4,
        ..NoiseTexture::default()
    };
    let distorted = NoiseTexture {
        distortion: 0.7,
        ..NoiseTexture::default()
    };
    for (name, tex) in [
        ("fac 3D defaults", defaults),
        ("fac 3D scale 2 detail 4", issue),
        ("fac 4D defaults", four_d),
        ("fac 3D distortion 0.7", distorted),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut s = 0.0f32;
                for p in &pts {
                    s += tex.fac(black_box([p[0], p[1], p[2]]), p[3]);
                }
                s
            })
        });
    }
    g.bench_function("eval 3D scale 2 detail 4", |b| {
        b.iter(|| {
            let mut s = 0.0f32;
            for p in &pts {
                let (f, c) = issue.eval(black_box([p[0], p[1], p[2]]), p[3]);
                s += f + c[1] + c[2];
            }
            s
        })
    });
    g.bench_function("materialx fractal3d 5 octaves", |b| {
        b.iter(|| {
            let mut s = 0.0f32;
            for p in &pts {
                s += fractal_noise_3d(black_box([p[0], p[1], p[2]]), 5, 2.0, 0.5);
            }
            s
        })
    });
    g.finish();
}

criterion_group!(benches, blender_noise);
criterion_main!(benches);

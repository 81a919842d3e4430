//! Particle swarm minimisation (constriction factor, inertia weight, personal
//! and global best), evaluated in parallel with rayon. Each particle owns its
//! random stream, seeded from the swarm seed and its index, and the global best
//! is reduced in a fixed order, so the result is bit-identical whatever the
//! number of threads.

use rand::rngs::SmallRng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

/// Swarm settings; every field has a documented default.
#[derive(Debug, Clone, PartialEq)]
pub struct SwarmSettings {
    /// Number of particles (default 40).
    pub particles: usize,
    /// Iterations of the plain swarm, phase 1 of the seed's Algorithm 1 (default 60).
    pub iterations: usize,
    /// Constriction factor chi (default 0.729, Clerc and Kennedy).
    pub chi: f64,
    /// Inertia weight w on the previous velocity (default 1.0: pure constriction).
    pub inertia: f64,
    /// Pull toward the particle's own best (default 2.05).
    pub c1: f64,
    /// Pull toward the swarm's best (default 2.05).
    pub c2: f64,
    /// Seed of the random streams (default 0).
    pub seed: u64,
}

impl Default for SwarmSettings {
    fn default() -> Self {
        SwarmSettings {
            particles: 40,
            iterations: 60,
            chi: 0.729,
            inertia: 1.0,
            c1: 2.05,
            c2: 2.05,
            seed: 0,
        }
    }
}

#[derive(Debug, Clone)]
struct Particle {
    x: Vec<f64>,
    v: Vec<f64>,
    best: Vec<f64>,
    best_value: f64,
    rng: SmallRng,
}

/// A swarm over the box `[lower, upper]`.
pub struct Swarm {
    particles: Vec<Particle>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    pub best: Vec<f64>,
    pub best_value: f64,
}

impl Swarm {
    /// Particles spread uniformly over the box; `seeds` (e.g. a physical guess)
    /// replace the first particles' positions.
    pub fn new(
        settings: &SwarmSettings,
        lower: Vec<f64>,
        upper: Vec<f64>,
        seeds: &[Vec<f64>],
        objective: &(dyn Fn(&[f64]) -> f64 + Sync),
    ) -> Self {
        let dim = lower.len();
        let mut particles: Vec<Particle> = (0..settings.particles.max(1))
            .map(|i| {
                let stream = settings.seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                let mut rng = SmallRng::seed_from_u64(stream);
                let x: Vec<f64> = match seeds.get(i) {
                    Some(s) => s.clone(),
                    None => (0..dim)
                        .map(|k| rng.random_range(lower[k]..=upper[k]))
                        .collect(),
                };
                let v = (0..dim)
                    .map(|k| 0.1 * (upper[k] - lower[k]) * rng.random_range(-1.0..=1.0))
                    .collect();
                Particle {
                    best: x.clone(),
                    x,
                    v,
                    best_value: f64::INFINITY,
                    rng,
                }
            })
            .collect();
        particles
            .par_iter_mut()
            .for_each(|p| p.best_value = objective(&p.x));
        let mut swarm = Swarm {
            particles,
            lower,
            upper,
            best: Vec::new(),
            best_value: f64::INFINITY,
        };
        swarm.update_global();
        swarm
    }

    /// The global best, reduced in particle order (deterministic).
    fn update_global(&mut self) {
        for p in &self.particles {
            if p.best_value < self.best_value {
                self.best_value = p.best_value;
                self.best = p.best.clone();
            }
        }
    }

    /// One iteration: move every particle, evaluate in parallel, update bests.
    pub fn step(&mut self, settings: &SwarmSettings, objective: &(dyn Fn(&[f64]) -> f64 + Sync)) {
        let global = self.best.clone();
        let (lower, upper) = (&self.lower, &self.upper);
        self.particles.par_iter_mut().for_each(|p| {
            for k in 0..p.x.len() {
                let (r1, r2): (f64, f64) = (p.rng.random(), p.rng.random());
                let v = settings.chi
                    * (settings.inertia * p.v[k]
                        + settings.c1 * r1 * (p.best[k] - p.x[k])
                        + settings.c2 * r2 * (global[k] - p.x[k]));
                let span = upper[k] - lower[k];
                p.v[k] = v.clamp(-span, span);
                p.x[k] = (p.x[k] + p.v[k]).clamp(lower[k], upper[k]);
            }
            let value = objective(&p.x);
            if value < p.best_value {
                p.best_value = value;
                p.best.copy_from_slice(&p.x);
            }
        });
        self.update_global();
    }

    /// Replace the global best (phase 2 moves it by a Gauss-Newton step).
    pub fn set_best(&mut self, x: Vec<f64>, value: f64) {
        if value < self.best_value {
            self.best_value = value;
            self.best = x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_minimum_of_a_bowl_deterministically() {
        let f = |x: &[f64]| -> f64 {
            x.iter()
                .enumerate()
                .map(|(i, v)| (v - 0.1 * i as f64).powi(2))
                .sum()
        };
        let settings = SwarmSettings {
            iterations: 200,
            ..SwarmSettings::default()
        };
        let run = || {
            let mut s = Swarm::new(&settings, vec![-1.0; 4], vec![1.0; 4], &[], &f);
            for _ in 0..settings.iterations {
                s.step(&settings, &f);
            }
            (s.best.clone(), s.best_value)
        };
        let (best, value) = run();
        assert!(value < 1e-8, "{value}");
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(run);
        assert_eq!(one.0, best);
    }
}

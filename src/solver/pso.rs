//! Particle swarm (placeholder; being written).

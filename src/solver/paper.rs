//! The seed paper's method (placeholder; being written).

//! The constants the physics read their materials by.

/// The magnetic constant μ0 in H/m (CODATA 2018).
pub const MU_0: f64 = 1.256_637_062_12e-6;

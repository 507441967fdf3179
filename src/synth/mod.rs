//! Amplification: one ×2 level on a global lattice of primitives, level chains and residual
//! correction.

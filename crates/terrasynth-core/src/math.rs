//! The transcendental functions of every path to a tile, a dictionary or an archive: the same bits
//! on every machine.
//!
//! The standard library's `f64::sin`, `exp`, `atan`, `ln`, `powf`… call the platform's C library,
//! and glibc picks the build of each function per CPU when the process starts. On x86-64 its FMA
//! builds of `atan`, `atan2`, `exp`, `sin`, `cos`, `tan`, `pow`, `log`, `log10` and `log2` give
//! another last bit than its SSE2 builds for up to one argument in 1,450
//! (`scripts/libm_builds.sh`; README, *Tests*, "The same bits on every machine"); on other
//! architectures and systems the C library is other code again.
//! A tile is a pure function of its world and its address, whatever the CPU (ARCHITECTURE,
//! *Deterministic*), so the code that computes tiles takes these functions from here instead: the
//! `libm` crate, musl's libm in plain Rust — IEEE 754 additions, multiplications and divisions in
//! a fixed order, which Rust never fuses — so one argument has one result everywhere.
//!
//! The workspace's `clippy.toml` disallows the standard methods. `sqrt` (correctly rounded by IEEE
//! 754), `abs`, `floor`, `round`, `to_degrees`, `to_radians`, `mul_add` (a correctly rounded
//! fused operation on every target) and `powi` (lowered by the compiler, not chosen at run time)
//! are the same bits everywhere and stay the standard ones.
//!
//! Names are the C library's: `log` is the natural logarithm, an `f` suffix marks the `f32`
//! function.

// Every function `clippy.toml` disallows in the standard library has its twin here (`ln` is
// `log`, `ln_1p` is `log1p`, `exp_m1` is `expm1`, `powf` is `pow`, `sin_cos` is `sincos`).
pub use libm::{
    acos, acosf, acosh, acoshf, asin, asinf, asinh, asinhf, atan, atan2, atan2f, atanf, atanh,
    atanhf, cbrt, cbrtf, cos, cosf, cosh, coshf, exp, exp2, exp2f, expf, expm1, expm1f, hypot,
    hypotf, log, log10, log10f, log1p, log1pf, log2, log2f, logf, pow, powf, sin, sincos, sincosf,
    sinf, sinh, sinhf, tan, tanf, tanh, tanhf,
};

#[cfg(test)]
mod tests {
    use super::*;

    /// Values any correct implementation must give (exactly, or within a few units in the last
    /// place), so that a wrong re-export (say `sin` bound to `cos`) fails.
    #[test]
    fn the_functions_are_the_ones_named() {
        let close = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * b.abs().max(1.0);
        assert_eq!(sin(0.0), 0.0);
        assert!(close(sin(std::f64::consts::FRAC_PI_6), 0.5));
        assert!(close(cos(std::f64::consts::FRAC_PI_3), 0.5));
        assert!(close(tan(std::f64::consts::FRAC_PI_4), 1.0));
        assert!(close(atan(1.0), std::f64::consts::FRAC_PI_4));
        assert!(close(atan2(1.0, -1.0), 3.0 * std::f64::consts::FRAC_PI_4));
        assert!(close(exp(1.0), std::f64::consts::E));
        assert!(close(log(std::f64::consts::E), 1.0));
        assert_eq!(log10(1000.0), 3.0);
        assert_eq!(log2(1024.0), 10.0);
        assert_eq!(pow(2.0, 10.0), 1024.0);
        assert_eq!(hypot(3.0, 4.0), 5.0);
        assert_eq!(cbrt(27.0), 3.0);
        let (s, c) = sincos(std::f64::consts::FRAC_PI_2);
        assert!(close(s, 1.0) && c.abs() < 1e-15);
        assert!((expf(1.0) - std::f32::consts::E).abs() <= f32::EPSILON * 4.0);
        assert_eq!(log10f(100.0), 2.0);
        assert_eq!(powf(3.0, 2.0), 9.0);
        assert!((sinf(std::f32::consts::FRAC_PI_2) - 1.0).abs() <= f32::EPSILON);
    }
}

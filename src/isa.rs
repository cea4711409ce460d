//! The instruction set the hot loops run in, chosen once at run time.
//!
//! A wheel for other machines is built for baseline x86-64 (SSE2), so that it runs on any
//! x86-64 CPU; a build from this source tree targets the building CPU instead (see
//! `.cargo/config.toml`), and then the two copies below are the same code. The per-iteration
//! loops (the vertex kernel over every pack, the per-vertex move) are compiled a second time
//! inside a function with AVX2 enabled, and [`run`] calls that copy when
//! the CPU has AVX2. `wide` fixes the representation of a pack at compile time, so in that copy
//! an eight-lane `f32` pack is still two 128-bit halves; what changes is the encoding (VEX
//! three-operand forms, fewer register copies). The numbers do not change: the two copies are
//! the same source, and no fused multiply-add is ever formed (even where the target has FMA,
//! LLVM does not contract `a * b + c` without being told, so every lane still performs the
//! scalar kernel's IEEE operations).
//!
//! `PERIDYN_SIMD=portable` in the environment (read once, at the first use) keeps the portable
//! copy on any CPU (the baseline build's SSE2 code in a wheel; in a native build, the same
//! code as the AVX2 copy).

use std::sync::atomic::{AtomicU8, Ordering};

/// Where the hot loops run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Isa {
    /// Baseline x86-64 (SSE2), or whatever the build targets on another architecture.
    Portable,
    /// x86-64 with AVX2.
    Avx2,
}

/// The choice, once made (0: not yet).
static CHOICE: AtomicU8 = AtomicU8::new(0);

impl Isa {
    fn code(self) -> u8 {
        match self {
            Isa::Portable => 1,
            Isa::Avx2 => 2,
        }
    }

    /// The best this CPU runs, unless `PERIDYN_SIMD=portable` asks for the baseline.
    fn detect() -> Self {
        if std::env::var("PERIDYN_SIMD").is_ok_and(|v| v == "portable") {
            return Isa::Portable;
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Isa::Avx2;
        }
        Isa::Portable
    }

    /// The instruction set [`run`] uses.
    pub fn current() -> Self {
        match CHOICE.load(Ordering::Relaxed) {
            1 => Isa::Portable,
            2 => Isa::Avx2,
            _ => {
                let isa = Self::detect();
                CHOICE.store(isa.code(), Ordering::Relaxed);
                isa
            }
        }
    }

    /// Makes [`run`] use `self` from now on (tests compare the two copies). Refused (false)
    /// for an instruction set the CPU lacks.
    #[cfg(test)]
    pub fn force(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        let available = self == Isa::Portable || std::arch::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let available = self == Isa::Portable;
        if available {
            CHOICE.store(self.code(), Ordering::Relaxed);
        }
        available
    }

    /// Undoes [`Isa::force`]: the next use chooses again.
    #[cfg(test)]
    pub fn reset() {
        CHOICE.store(0, Ordering::Relaxed);
    }
}

/// Calls `f`, compiled for [`Isa::current`]. `f` should be an `#[inline(always)]` closure
/// calling an `#[inline(always)]` function that holds the loop, so that the loop is compiled
/// into each copy (else LLVM may keep one baseline copy and call it from both).
#[inline(always)]
pub fn run<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if Isa::current() == Isa::Avx2 {
        // SAFETY: `Isa::current` is `Avx2` only on a CPU that has AVX2.
        return unsafe { with_avx2(f) };
    }
    f()
}

/// `f()` compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

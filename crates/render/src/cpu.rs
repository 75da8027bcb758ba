//! The processor's instruction sets, found at run time. Where it has AVX2, BMI1, BMI2
//! and LZCNT, the hottest page loops (the scan converter's strokes and rings, the gray
//! layer's flush, the PNG encoder's Up rows) run as twins compiled for them; elsewhere,
//! as the baseline x86-64 code. The twins do the same operations in the same order
//! (never a fused multiply-add), so a page's bytes do not depend on the processor; tests
//! draw and encode pages on both paths and compare them.

/// Whether the processor has AVX2, BMI1, BMI2 and LZCNT (x86-64 only; checked at run
/// time, the check cached by the standard library). In this crate's tests, false while
/// the thread asks for the baseline path ([`baseline_only`]), to compare the two.
#[inline]
pub(crate) fn x86_fast() -> bool {
    #[cfg(test)]
    if BASELINE.with(std::cell::Cell::get) {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

#[cfg(test)]
thread_local! {
    /// Whether this thread draws and encodes on the baseline path only ([`x86_fast`]).
    static BASELINE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f` with this thread drawing and encoding on the baseline instruction set's path
/// only (`true`) or as the processor allows (`false`), for tests comparing the two.
#[cfg(test)]
pub(crate) fn baseline_only<T>(on: bool, f: impl FnOnce() -> T) -> T {
    let was = BASELINE.with(|b| b.replace(on));
    let out = f();
    BASELINE.with(|b| b.set(was));
    out
}

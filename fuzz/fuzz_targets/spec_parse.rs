#![no_main]
//! The atlas spec parser: any text; whatever parses must also enumerate.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        match coupler_atlas::Spec::parse(text, "fuzz.toml") {
            Ok(spec) => {
                if spec.combinations() <= 100_000 {
                    let _ = spec.enumerate();
                }
            }
            Err(e) => assert!(e.line >= 1),
        }
    }
});

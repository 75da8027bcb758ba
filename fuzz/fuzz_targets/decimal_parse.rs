#![no_main]
//! The exact decimal parser behind every length on the command line and in specs.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(d) = text.parse::<coupler_atlas::Decimal>() {
            let back: coupler_atlas::Decimal = d.to_string().parse().expect("Display output parses");
            assert_eq!(back, d);
        }
    }
});

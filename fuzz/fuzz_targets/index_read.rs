#![no_main]
//! The index reader: any bytes.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = coupler_atlas::Index::from_slice(data);
});

#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| tspace::fuzz_targets::core(data));

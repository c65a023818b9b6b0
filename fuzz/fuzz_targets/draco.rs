#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| tspace_testkit::fuzz::draco(data));

#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    hitex_io::fuzz::run(hitex_io::fuzz::Target::HbtfPca, data);
});

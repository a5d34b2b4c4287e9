//! hil-sim's scenario files (TOML, from users and the campaign).
//!
//! Asserts: no panic on any text: a bad scenario is an error with a message.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = core::str::from_utf8(data) else {
        return;
    };
    let _ = hil_sim::scenario::Scenario::parse(text);
});

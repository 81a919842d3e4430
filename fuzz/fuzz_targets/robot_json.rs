//! Bytes -> JSON value -> `Robot::from_value`. Refusals are fine, panics are not.
#![no_main]

use libfuzzer_sys::fuzz_target;
use softspine::{Robot, Value};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(value) = Value::from_json_str(text) {
        let _ = Robot::from_value(&value);
    }
});

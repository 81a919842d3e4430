//! Mutated JSON scenes: reading one may refuse it, but must never panic or
//! overflow the stack (deterministic, a few thousand inputs, well under 2 s).

use rand::rngs::SmallRng;
use rand::{RngExt, SeedableRng};
use softspine::Scene;
use std::panic;

const BASE: &str = r#"{"name": "mutant", "length": 1.0,
 "stiffness": {"E": 2e11, "G": 8e10, "diameter": 0.003},
 "rest_curvature": [[1.0, 0.5], [0.0, -2.0]],
 "gravity": {"linear_density": 0.2, "vector": [0, 0, -9.81]},
 "tip_force": [0.1, 0.0, -0.3], "tip_moment": [0, 0, 0.01],
 "base_quaternion": [1, 0, 0, 0],
 "tip": {"type": "pinned", "position": [0.2, 0.1, 0.9]},
 "guides": [{"s": 0.5, "position": [0.05, 0.0, 0.45]}],
 "point_loads": [{"s": 0.25, "force": [0, 0, -1]}]}"#;

/// Numbers at the edges of (or beyond) what JSON and a double can hold.
const ODD_NUMBERS: &[&str] = &[
    "1e400",
    "-1e400",
    "1e308",
    "1.7976931348623157e308",
    "1e-400",
    "5e-324",
    "-0",
    "0",
    "NaN",
    "Infinity",
    "-Infinity",
    "nan",
    "1e",
    "-",
    ".5",
    "1.",
    "00",
    "0x10",
    "123456789012345678901234567890",
    "18446744073709551616",
    "-9223372036854775809",
    "1e-0000000000000000000000000001",
    "true",
    "null",
    "\"1\"",
    "[]",
    "{}",
];

const ODD_TEXT: &[&str] = &[
    "\u{0}",
    "\"",
    ",",
    ":",
    "é",
    "\\",
    "\\u",
    "\u{feff}",
    "/*",
    "'",
    "\"length\": 2, ",
];

const DEPTHS: &[usize] = &[1, 31, 32, 33, 200, 30_000];

/// Byte ranges of the number tokens of `text` (outside strings).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut in_string = false;
    let mut i = 0;
    while i < bytes.len() {
        let b = bytes[i];
        if b == b'"' {
            in_string = !in_string;
        }
        if !in_string && (b.is_ascii_digit() || b == b'-') {
            let end = (i + 1..bytes.len())
                .find(|&j| !matches!(bytes[j], b'0'..=b'9' | b'.' | b'e' | b'E' | b'+' | b'-'))
                .unwrap_or(bytes.len());
            out.push((i, end));
            i = end;
        } else {
            i += 1;
        }
    }
    out
}

/// Indices of characters that may be replaced or removed without splitting a
/// UTF-8 sequence.
fn boundaries(text: &str) -> Vec<usize> {
    text.char_indices().map(|(i, _)| i).collect()
}

fn pick<'a, T>(rng: &mut SmallRng, items: &'a [T]) -> Option<&'a T> {
    (!items.is_empty()).then(|| &items[rng.random_range(0..items.len())])
}

fn mutate(text: &str, rng: &mut SmallRng) -> String {
    let mut t = text.to_owned();
    let brackets: Vec<usize> = t
        .char_indices()
        .filter(|(_, c)| "[]{}".contains(*c))
        .map(|(i, _)| i)
        .collect();
    let braces: Vec<usize> = t.match_indices('{').map(|(i, _)| i).collect();
    let spots = numbers(&t);
    let cuts = boundaries(&t);
    match rng.random_range(0..7) {
        0 | 1 => {
            if let Some(&(a, b)) = pick(rng, &spots) {
                let odd = *pick(rng, ODD_NUMBERS).unwrap();
                t.replace_range(a..b, odd);
            }
        }
        2 => {
            // Delete or duplicate a bracket.
            if let Some(&i) = pick(rng, &brackets) {
                let c = t.remove(i);
                if rng.random_bool(0.5) {
                    t.insert_str(i, &format!("{c}{c}"));
                }
            }
        }
        3 => {
            // Bury a number deep in lists.
            if let Some(&(a, b)) = pick(rng, &spots) {
                let d = *pick(rng, DEPTHS).unwrap();
                let buried = format!("{}{}{}", "[".repeat(d), &t[a..b], "]".repeat(d));
                t.replace_range(a..b, &buried);
            }
        }
        4 => {
            if let Some(&i) = pick(rng, &cuts) {
                t.truncate(i);
            }
        }
        5 => {
            if let Some(&i) = pick(rng, &cuts) {
                t.insert_str(i, pick(rng, ODD_TEXT).unwrap());
            }
        }
        _ => {
            // A duplicate key right after an opening brace.
            if let Some(&i) = pick(rng, &braces) {
                let key = pick(rng, &["length", "s", "type", "kx", "E"]).unwrap();
                t.insert_str(i + 1, &format!("\"{key}\": 1, "));
            }
        }
    }
    t
}

#[test]
fn mutated_scenes_are_refused_without_panicking() {
    Scene::from_json_str(BASE).expect("the base scene is valid");
    let mut rng = SmallRng::seed_from_u64(2024);
    let (mut accepted, mut refused) = (0, 0);
    for _ in 0..4000 {
        let mut text = BASE.to_owned();
        for _ in 0..rng.random_range(1..4) {
            text = mutate(&text, &mut rng);
        }
        let result = panic::catch_unwind(|| Scene::from_json_str(&text));
        match result {
            Ok(Ok(_)) => accepted += 1,
            Ok(Err(e)) => {
                refused += 1;
                assert!(!e.to_string().is_empty());
            }
            Err(_) => panic!(
                "Scene::from_json_str panicked on {:?}",
                &text[..text.len().min(300)]
            ),
        }
    }
    // Both outcomes occur, so that the mutations reach the validator as well as the parser
    // (84 of 4000 accepted since the validator refuses what no rod can mean, such as a
    // diameter mutated past the length).
    assert!(
        accepted > 50 && refused > 1000,
        "{accepted} accepted, {refused} refused"
    );
}

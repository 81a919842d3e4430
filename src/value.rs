//! A format-neutral tree of scene input (JSON, TOML or a Python dict), so that
//! one validator names the offending key whatever the source.

use crate::error::{Error, Result};
use serde::de::{self, DeserializeSeed, MapAccess, SeqAccess, Visitor};
use std::cell::RefCell;
use std::collections::HashSet;
use std::fmt;

/// Deepest nesting of lists and tables accepted from any source (a scene needs
/// four levels): deeper input is refused by its path instead of exhausting the
/// stack of a recursive reader.
pub const MAX_DEPTH: usize = 32;

/// A parsed input value. Numbers stay `f64` so that NaN and infinities reach the
/// validator (and are refused there by key) instead of failing in a parser.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Null,
    Bool(bool),
    Number(f64),
    String(String),
    List(Vec<Value>),
    Map(Vec<(String, Value)>),
}

impl Value {
    /// A short name of the value's kind, for error messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Value::Null => "null",
            Value::Bool(_) => "a boolean",
            Value::Number(_) => "a number",
            Value::String(_) => "a string",
            Value::List(_) => "a list",
            Value::Map(_) => "a table",
        }
    }

    /// Read a `.json` or `.toml` file (by its extension).
    pub fn from_file(path: &std::path::Path) -> Result<Value> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::Parse(format!("{}: {e}", path.display())))?;
        match path.extension().and_then(|e| e.to_str()) {
            Some("json") => Value::from_json_str(&text),
            Some("toml") => Value::from_toml_str(&text),
            _ => Err(Error::Parse(format!(
                "{}: expected a .json or .toml file",
                path.display()
            ))),
        }
    }

    /// Parse JSON text. A duplicate key is refused (serde_json's own map keeps
    /// the last value silently), and an error inside the document, such as a
    /// number out of range, names the key it belongs to.
    pub fn from_json_str(text: &str) -> Result<Value> {
        let path = RefCell::new(Vec::new());
        let mut de = serde_json::Deserializer::from_str(text);
        let parsed = JsonSeed { path: &path }
            .deserialize(&mut de)
            .and_then(|v| de.end().map(|()| v));
        parsed.map_err(|e| {
            let reason = format!("invalid JSON: {e}");
            match path.into_inner() {
                at if at.is_empty() => Error::Parse(reason),
                at => Error::scene(render(&at), reason),
            }
        })
    }

    /// Parse TOML text (the format refuses duplicate keys and bounds nesting itself).
    pub fn from_toml_str(text: &str) -> Result<Value> {
        let v: toml::Value = toml::from_str(text)
            .map_err(|e| Error::Parse(format!("invalid TOML: {}", one_line(text, &e))))?;
        Ok(Value::from(&v))
    }
}

/// A TOML error on one line (its `Display` quotes the source over several).
fn one_line(text: &str, e: &toml::de::Error) -> String {
    let message = e.message().trim().replace('\n', "; ");
    match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.chars().rev().take_while(|&c| c != '\n').count() + 1;
            format!("{message} at line {line} column {column}")
        }
        None => message,
    }
}

enum Segment {
    Key(String),
    Index(usize),
}

/// `stiffness.kx`, `rest_curvature[1]`: keys as the validator names them.
fn render(path: &[Segment]) -> String {
    let mut out = String::new();
    for segment in path {
        match segment {
            Segment::Key(k) if out.is_empty() => out.push_str(k),
            Segment::Key(k) => {
                out.push('.');
                out.push_str(k);
            }
            Segment::Index(i) => out.push_str(&format!("[{i}]")),
        }
    }
    out
}

/// Reads one JSON value, keeping the path of the value being read: a segment is
/// popped only once its value is read, so after an error the path names the
/// failing entry.
#[derive(Clone, Copy)]
struct JsonSeed<'a> {
    path: &'a RefCell<Vec<Segment>>,
}

impl JsonSeed<'_> {
    fn enter<E: de::Error>(&self) -> std::result::Result<(), E> {
        if self.path.borrow().len() >= MAX_DEPTH {
            return Err(E::custom(format!("nested deeper than {MAX_DEPTH} levels")));
        }
        Ok(())
    }
}

impl<'de> DeserializeSeed<'de> for JsonSeed<'_> {
    type Value = Value;

    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> std::result::Result<Value, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for JsonSeed<'_> {
    type Value = Value;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_unit<E>(self) -> std::result::Result<Value, E> {
        Ok(Value::Null)
    }

    fn visit_bool<E>(self, b: bool) -> std::result::Result<Value, E> {
        Ok(Value::Bool(b))
    }

    fn visit_i64<E>(self, i: i64) -> std::result::Result<Value, E> {
        Ok(Value::Number(i as f64))
    }

    fn visit_u64<E>(self, u: u64) -> std::result::Result<Value, E> {
        Ok(Value::Number(u as f64))
    }

    fn visit_f64<E>(self, x: f64) -> std::result::Result<Value, E> {
        Ok(Value::Number(x))
    }

    fn visit_str<E>(self, s: &str) -> std::result::Result<Value, E> {
        Ok(Value::String(s.to_owned()))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<Value, A::Error> {
        self.enter()?;
        let mut items = Vec::new();
        loop {
            self.path.borrow_mut().push(Segment::Index(items.len()));
            let item = seq.next_element_seed(self)?;
            self.path.borrow_mut().pop();
            match item {
                Some(v) => items.push(v),
                None => return Ok(Value::List(items)),
            }
        }
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> std::result::Result<Value, A::Error> {
        self.enter()?;
        let mut entries = Vec::new();
        let mut seen = HashSet::new();
        while let Some(key) = map.next_key::<String>()? {
            self.path.borrow_mut().push(Segment::Key(key.clone()));
            if !seen.insert(key.clone()) {
                return Err(de::Error::custom("duplicate key"));
            }
            let v = map.next_value_seed(self)?;
            self.path.borrow_mut().pop();
            entries.push((key, v));
        }
        Ok(Value::Map(entries))
    }
}

/// The formats a tree is written in (read back by [`Value::from_file`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Json,
    Toml,
}

impl Format {
    /// The format of a file's name (`.json` or `.toml`), refused otherwise.
    pub fn of_path(path: &std::path::Path) -> Result<Format> {
        match path.extension().and_then(|e| e.to_str()) {
            Some("json") => Ok(Format::Json),
            Some("toml") => Ok(Format::Toml),
            _ => Err(Error::argument(
                "path",
                format!("expected a .json or .toml file, got {}", path.display()),
            )),
        }
    }
}

impl Value {
    /// The tree as text in `format`, read back to the same tree (numbers
    /// in their shortest round-trip form, an integral one as an integer,
    /// a table's keys in order). A table's null entries are left out (an
    /// absent key reads as its default, and TOML has no null); a null in a
    /// list, a non-table at the top (TOML) and a non-finite number (JSON
    /// has none) are refused by their path.
    pub fn to_text(&self, format: Format) -> Result<String> {
        check_writable(self, format, &mut Vec::new())?;
        match format {
            Format::Json => {
                let mut out = String::new();
                write_json(self, 0, &mut out);
                out.push('\n');
                Ok(out)
            }
            Format::Toml => {
                if !matches!(self, Value::Map(_)) {
                    return Err(Error::Parse(format!(
                        "TOML needs a table at the top, got {}",
                        self.kind()
                    )));
                }
                toml::to_string(self).map_err(|e| Error::Parse(format!("TOML: {e}")))
            }
        }
    }

    /// Write the tree to a `.json` or `.toml` file (by its extension).
    pub fn write_file(&self, path: &std::path::Path) -> Result<()> {
        let text = self.to_text(Format::of_path(path)?)?;
        std::fs::write(path, text)
            .map_err(|e| Error::argument("path", format!("{}: {e}", path.display())))
    }
}

fn check_writable(v: &Value, format: Format, path: &mut Vec<Segment>) -> Result<()> {
    let refuse = |path: &[Segment], reason: &str| Err(Error::scene(render(path), reason));
    match v {
        Value::Number(x) if format == Format::Json && !x.is_finite() => {
            refuse(path, &format!("JSON has no {x}: write a .toml file"))
        }
        Value::List(items) => {
            for (i, item) in items.iter().enumerate() {
                path.push(Segment::Index(i));
                if *item == Value::Null {
                    return refuse(path, "a list cannot hold null in a file");
                }
                check_writable(item, format, path)?;
                path.pop();
            }
            Ok(())
        }
        Value::Map(entries) => {
            for (key, item) in entries {
                path.push(Segment::Key(key.clone()));
                check_writable(item, format, path)?;
                path.pop();
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

/// JSON a person reads: a table's entries one a line, indented; a list of
/// numbers on one line; numbers as [`Value`]'s `Serialize` writes them.
fn write_json(v: &Value, depth: usize, out: &mut String) {
    let indent = |out: &mut String, depth: usize| out.push_str(&"  ".repeat(depth));
    let scalar = |v: &Value| serde_json::to_string(v).unwrap_or_default();
    match v {
        Value::Map(entries) => {
            let kept: Vec<_> = entries.iter().filter(|(_, v)| *v != Value::Null).collect();
            if kept.is_empty() {
                out.push_str("{}");
                return;
            }
            out.push_str("{\n");
            for (i, (key, item)) in kept.iter().enumerate() {
                indent(out, depth + 1);
                out.push_str(&scalar(&Value::String(key.clone())));
                out.push_str(": ");
                write_json(item, depth + 1, out);
                out.push_str(if i + 1 < kept.len() { ",\n" } else { "\n" });
            }
            indent(out, depth);
            out.push('}');
        }
        Value::List(items) if items.iter().any(|x| matches!(x, Value::Map(_))) => {
            out.push_str("[\n");
            for (i, item) in items.iter().enumerate() {
                indent(out, depth + 1);
                write_json(item, depth + 1, out);
                out.push_str(if i + 1 < items.len() { ",\n" } else { "\n" });
            }
            indent(out, depth);
            out.push(']');
        }
        Value::List(items) => {
            let parts: Vec<String> = items
                .iter()
                .map(|item| {
                    let mut part = String::new();
                    write_json(item, depth + 1, &mut part);
                    part
                })
                .collect();
            out.push('[');
            out.push_str(&parts.join(", "));
            out.push(']');
        }
        other => out.push_str(&scalar(other)),
    }
}

/// Integral numbers below this are written as integers (exact in a double).
const EXACT_INTEGER: f64 = 9_007_199_254_740_992.0;

impl serde::Serialize for Value {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::{SerializeMap, SerializeSeq};
        match self {
            Value::Null => s.serialize_unit(),
            Value::Bool(b) => s.serialize_bool(*b),
            Value::Number(x)
                if x.fract() == 0.0
                    && x.abs() < EXACT_INTEGER
                    && !(*x == 0.0 && x.is_sign_negative()) =>
            {
                s.serialize_i64(*x as i64)
            }
            Value::Number(x) => s.serialize_f64(*x),
            Value::String(text) => s.serialize_str(text),
            Value::List(items) => {
                let mut seq = s.serialize_seq(Some(items.len()))?;
                for item in items {
                    seq.serialize_element(item)?;
                }
                seq.end()
            }
            Value::Map(entries) => {
                let kept = entries.iter().filter(|(_, v)| *v != Value::Null);
                let mut map = s.serialize_map(Some(kept.clone().count()))?;
                for (key, item) in kept {
                    map.serialize_entry(key, item)?;
                }
                map.end()
            }
        }
    }
}

impl From<&toml::Value> for Value {
    fn from(v: &toml::Value) -> Self {
        use toml::Value as T;
        match v {
            T::Boolean(b) => Value::Bool(*b),
            T::Integer(i) => Value::Number(*i as f64),
            T::Float(x) => Value::Number(*x),
            T::String(s) => Value::String(s.clone()),
            T::Datetime(d) => Value::String(d.to_string()),
            T::Array(a) => Value::List(a.iter().map(Value::from).collect()),
            T::Table(m) => Value::Map(m.iter().map(|(k, v)| (k.clone(), Value::from(v))).collect()),
        }
    }
}

impl Value {
    /// The number at `path` in a value tree: keys joined by dots, list
    /// indices in brackets (`"stiffness.E"`, `"tip_force[2]"`,
    /// `"rest_curvature[3][1]"`). The error names the path and what it found.
    pub fn number_at_mut(&mut self, path: &str) -> Result<&mut f64> {
        let bad = |reason: String| Error::argument(path.to_string(), reason);
        let mut node = self;
        for part in path.split('.') {
            let (key, indices) = match part.find('[') {
                Some(i) => (&part[..i], &part[i..]),
                None => (part, ""),
            };
            if !key.is_empty() {
                node = match node {
                    Value::Map(entries) => entries
                        .iter_mut()
                        .find(|(k, _)| k == key)
                        .map(|(_, v)| v)
                        .ok_or_else(|| bad(format!("no field {key:?} here")))?,
                    other => {
                        return Err(bad(format!(
                            "{key:?}: expected a table, got {}",
                            other.kind()
                        )))
                    }
                };
            }
            for index in indices.split(']').filter(|s| !s.is_empty()) {
                let i: usize = index
                    .strip_prefix('[')
                    .and_then(|s| s.parse().ok())
                    .ok_or_else(|| bad(format!("{index}]: not an index")))?;
                node = match node {
                    Value::List(items) => {
                        let len = items.len();
                        items
                            .get_mut(i)
                            .ok_or_else(|| bad(format!("index {i} out of range (length {len})")))?
                    }
                    other => return Err(bad(format!("expected a list, got {}", other.kind()))),
                };
            }
        }
        match node {
            Value::Number(x) => Ok(x),
            other => Err(bad(format!("expected a number, got {}", other.kind()))),
        }
    }

    /// Every number of the tree with its path, in the syntax
    /// [`Value::number_at_mut`] reads (`"sections[1].stiffness.kx"`), in
    /// the tree's order.
    pub fn numbers(&self) -> Vec<(String, f64)> {
        fn walk(v: &Value, path: &mut String, out: &mut Vec<(String, f64)>) {
            let len = path.len();
            match v {
                Value::Number(x) => out.push((path.clone(), *x)),
                Value::List(items) => {
                    for (i, item) in items.iter().enumerate() {
                        path.push_str(&format!("[{i}]"));
                        walk(item, path, out);
                        path.truncate(len);
                    }
                }
                Value::Map(entries) => {
                    for (key, item) in entries {
                        if !path.is_empty() {
                            path.push('.');
                        }
                        path.push_str(key);
                        walk(item, path, out);
                        path.truncate(len);
                    }
                }
                _ => {}
            }
        }
        let mut out = Vec::new();
        walk(self, &mut String::new(), &mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(json: &str) -> (String, String) {
        match Value::from_json_str(json) {
            Err(Error::InvalidScene { key, reason }) => (key, reason),
            other => panic!("expected a refusal naming a key, got {other:?}"),
        }
    }

    #[test]
    fn a_tree_written_reads_back_the_same() {
        let text = r#"{"a": 1, "b": [0.1, -0.0, 1e-300, 3], "c": {"d": "x", "e": [[1, 2], [3, 4]]},
                       "f": [{"g": true}, {"g": false}], "h": null}"#;
        let tree = Value::from_json_str(text).unwrap();
        let Value::Map(mut without_null) = tree.clone() else {
            unreachable!()
        };
        without_null.retain(|(k, _)| k != "h");
        for format in [Format::Json, Format::Toml] {
            let written = tree.to_text(format).unwrap();
            let back = match format {
                Format::Json => Value::from_json_str(&written),
                Format::Toml => Value::from_toml_str(&written),
            };
            assert_eq!(back.unwrap(), Value::Map(without_null.clone()), "{written}");
        }
    }

    #[test]
    fn what_a_file_cannot_hold_is_refused_by_path() {
        let infinite = Value::Map(vec![(
            "k".into(),
            Value::List(vec![Value::Number(f64::INFINITY)]),
        )]);
        let message = infinite.to_text(Format::Json).unwrap_err().to_string();
        assert!(message.starts_with("k[0]: JSON has no inf"), "{message}");
        assert!(infinite.to_text(Format::Toml).is_ok());
        let null_in_list = Value::Map(vec![("k".into(), Value::List(vec![Value::Null]))]);
        let message = null_in_list.to_text(Format::Toml).unwrap_err().to_string();
        assert!(message.starts_with("k[0]: "), "{message}");
    }

    #[test]
    fn duplicate_keys_are_refused_by_path() {
        let (key, reason) = refusal(r#"{"length": 1, "length": 2}"#);
        assert_eq!(key, "length");
        assert!(reason.contains("duplicate key"), "{reason}");
        let (key, _) = refusal(r#"{"tip": {"position": [0, 0, 1], "position": [1, 0, 0]}}"#);
        assert_eq!(key, "tip.position");
        let (key, _) = refusal(r#"{"guides": [{"s": 1}, {"s": 1, "s": 2}]}"#);
        assert_eq!(key, "guides[1].s");
    }

    #[test]
    fn errors_inside_the_document_name_the_entry() {
        let (key, reason) = refusal(r#"{"stiffness": {"kx": 1e400}}"#);
        assert_eq!(key, "stiffness.kx");
        assert!(reason.contains("out of range"), "{reason}");
        let (key, _) = refusal(r#"{"tip_force": [0, 1, -1e999]}"#);
        assert_eq!(key, "tip_force[2]");
        // Syntax errors outside any value have no key.
        assert!(matches!(
            Value::from_json_str("{length: 1}"),
            Err(Error::Parse(_))
        ));
        assert!(matches!(Value::from_json_str("{} x"), Err(Error::Parse(_))));
    }

    #[test]
    fn nesting_is_bounded() {
        let ok = format!("{}1{}", "[".repeat(MAX_DEPTH), "]".repeat(MAX_DEPTH));
        assert!(Value::from_json_str(&ok).is_ok());
        let deep = format!(
            "{{\"a\": {}1{}}}",
            "[".repeat(MAX_DEPTH),
            "]".repeat(MAX_DEPTH)
        );
        let (key, reason) = refusal(&deep);
        assert!(key.starts_with("a[0]"), "{key}");
        assert!(reason.contains("nested deeper than 32"), "{reason}");
        let very_deep = "[".repeat(30_000);
        assert!(Value::from_json_str(&very_deep).is_err());
    }

    #[test]
    fn numbers_are_correctly_rounded() {
        for x in [
            0.1,
            1.0 / 3.0,
            2.2250738585072014e-308,
            5e-324,
            1.7976931348623157e308,
        ] {
            let text = serde_json::to_string(&x).unwrap();
            assert_eq!(Value::from_json_str(&text).unwrap(), Value::Number(x));
        }
        // Integers beyond u64 still read as the nearest double.
        assert_eq!(
            Value::from_json_str("123456789012345678901234567890").unwrap(),
            Value::Number(1.2345678901234568e29)
        );
    }

    #[test]
    fn toml_errors_fit_on_one_line() {
        let e = Value::from_toml_str("length = 1\nlength = 2\n").unwrap_err();
        let message = e.to_string();
        assert!(!message.contains('\n'), "{message}");
        assert!(message.contains("line 2"), "{message}");
    }
}

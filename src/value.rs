//! A format-neutral tree of scene input (JSON, TOML or a Python dict), so that
//! one validator names the offending key whatever the source.

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
}

impl From<&serde_json::Value> for Value {
    fn from(v: &serde_json::Value) -> Self {
        use serde_json::Value as J;
        match v {
            J::Null => Value::Null,
            J::Bool(b) => Value::Bool(*b),
            J::Number(n) => Value::Number(n.as_f64().unwrap_or(f64::NAN)),
            J::String(s) => Value::String(s.clone()),
            J::Array(a) => Value::List(a.iter().map(Value::from).collect()),
            J::Object(m) => {
                Value::Map(m.iter().map(|(k, v)| (k.clone(), Value::from(v))).collect())
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

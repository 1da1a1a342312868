//! Layering a configuration: merging a file's table and `--set key=value` overrides over the
//! defaults, key by key, with messages that name the key, its origin and the valid keys.

use std::fmt;
use std::path::Path;

use toml::{Table, Value};

use super::{ConfigError, SimConfig, BARE_KEYS};

/// Where a key was given, for messages.
#[derive(Debug, Clone, Copy)]
pub(super) enum Origin<'a> {
    /// The configuration file.
    File(&'a Path),
    /// A `--set` argument (as given).
    Set(&'a str),
}

impl fmt::Display for Origin<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::File(path) => write!(f, "config file {}", path.display()),
            Origin::Set(text) => write!(f, "--set `{text}`"),
        }
    }
}

/// Reads the value of a `--set key=value` override (or of a `vtq sweep --grid` list): TOML
/// (`16`, `0.75`, `true`, `"queues"`), or a bare word starting with a letter, taken as a string
/// (`queues`). The error says why the text is neither.
pub fn parse_override_value(raw: &str) -> Result<Value, String> {
    let raw = raw.trim();
    match raw.parse::<Value>() {
        Ok(value) => Ok(value),
        Err(_) if raw.starts_with(|c: char| c.is_ascii_alphabetic()) => {
            Ok(Value::String(raw.to_string()))
        }
        Err(e) => Err(format!(
            "`{raw}` is not a TOML value: {} (a string that does not start with a letter \
             must be quoted)",
            e.message().trim()
        )),
    }
}

/// Applies one `--set key=value` override to `merged`.
pub(super) fn apply_override(
    defaults: &Table,
    merged: &mut Table,
    text: &str,
) -> Result<(), ConfigError> {
    let bad = |reason: &str| ConfigError::Override {
        text: text.to_string(),
        reason: reason.to_string(),
    };
    let (key, raw) = text
        .split_once('=')
        .ok_or_else(|| bad("expected key=value, e.g. hw.repack_threshold=16"))?;
    let key = key.trim();
    if key.is_empty() {
        return Err(bad("the key before '=' is empty"));
    }
    let value = parse_override_value(raw).map_err(|reason| bad(&reason))?;
    let full = if BARE_KEYS.contains(&key) {
        format!("workload.{key}")
    } else {
        key.to_string()
    };
    let parts: Vec<&str> = full.split('.').map(str::trim).collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(bad("the key has an empty part (expected section.key)"));
    }
    // Nest the value under its dotted key and merge it like a file's table.
    let (last, init) = parts.split_last().unwrap_or((&"", &[]));
    let mut nested = Table::new();
    nested.insert(last.to_string(), value);
    for part in init.iter().rev() {
        let mut outer = Table::new();
        outer.insert(part.to_string(), Value::Table(nested));
        nested = outer;
    }
    merge(
        defaults,
        merged,
        &nested,
        &mut Vec::new(),
        Origin::Set(text),
    )
}

/// Merges `given` into `merged` (both under the dotted path `path`), checking every key exists
/// in `defaults` and every value deserializes for its key.
pub(super) fn merge(
    defaults: &Table,
    merged: &mut Table,
    given: &Table,
    path: &mut Vec<String>,
    origin: Origin,
) -> Result<(), ConfigError> {
    for (key, value) in given {
        path.push(key.clone());
        let dotted = path.join(".");
        let Some(default) = defaults.get(key) else {
            return Err(ConfigError::UnknownKey {
                origin: origin.to_string(),
                key: dotted,
                hint: unknown_key_hint(defaults, path, origin),
            });
        };
        match (default, value) {
            (Value::Table(sub_default), Value::Table(sub_given)) => {
                let Some(Value::Table(sub_merged)) = merged.get_mut(key) else {
                    return Err(ConfigError::Toml(format!(
                        "section `{dotted}` missing from the merged configuration"
                    )));
                };
                merge(sub_default, sub_merged, sub_given, path, origin)?;
            }
            (Value::Table(sub_default), _) => {
                return Err(ConfigError::Type {
                    origin: origin.to_string(),
                    key: dotted.clone(),
                    value: value.to_string(),
                    reason: format!(
                        "`{dotted}` is a section; set one of its keys ({})",
                        key_list(sub_default, &dotted)
                    ),
                });
            }
            _ => {
                check_leaf(path, value).map_err(|reason| ConfigError::Type {
                    origin: origin.to_string(),
                    key: dotted.clone(),
                    value: value.to_string(),
                    reason,
                })?;
                merged.insert(key.clone(), value.clone());
            }
        }
        path.pop();
    }
    Ok(())
}

/// Checks that `value` deserializes for the key at `path`: the defaults with that one key
/// replaced must form a [`SimConfig`]. Returns the deserializer's reason otherwise.
fn check_leaf(path: &[String], value: &Value) -> Result<(), String> {
    let mut root = SimConfig::default().to_table().map_err(|e| e.to_string())?;
    let mut table = &mut root;
    let (last, init) = path.split_last().ok_or("empty key")?;
    for part in init {
        match table.get_mut(part) {
            Some(Value::Table(t)) => table = t,
            _ => return Err(format!("`{part}` is not a section")),
        }
    }
    table.insert(last.clone(), value.clone());
    Value::Table(root)
        .try_into::<SimConfig>()
        .map(|_| ())
        .map_err(|e| e.message().to_string())
}

/// The hint of an unknown key at `path` whose section's defaults are `section`: a key of the
/// same name elsewhere, and the valid keys of the section.
fn unknown_key_hint(section: &Table, path: &[String], origin: Origin) -> String {
    let name = path.last().map_or("", String::as_str);
    let mut elsewhere = Vec::new();
    if let Ok(root) = SimConfig::default().to_table() {
        find_leaves(&root, name, &mut Vec::new(), &mut elsewhere);
    }
    let section_name = path[..path.len().saturating_sub(1)].join(".");
    let mut hint = String::new();
    if let Some(other) = elsewhere.first() {
        hint.push_str(&format!("did you mean `{other}`? "));
    }
    if section_name.is_empty() {
        hint.push_str(&format!(
            "valid sections: {}",
            section.keys().cloned().collect::<Vec<_>>().join(", ")
        ));
        if let Origin::Set(_) = origin {
            hint.push_str(&format!(
                " (keys without a section: {})",
                BARE_KEYS.join(", ")
            ));
        }
    } else {
        hint.push_str(&format!(
            "valid keys of [{section_name}]: {}",
            key_list(section, &section_name)
        ));
    }
    hint
}

/// The keys of a section's defaults, comma-separated, subsections as `[path.sub]`.
fn key_list(section: &Table, section_name: &str) -> String {
    section
        .iter()
        .map(|(k, v)| match v {
            Value::Table(_) => format!("[{section_name}.{k}]"),
            _ => k.clone(),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Collects the dotted paths of every leaf key called `name` under `table`.
fn find_leaves(table: &Table, name: &str, path: &mut Vec<String>, out: &mut Vec<String>) {
    for (k, v) in table {
        path.push(k.clone());
        match v {
            Value::Table(sub) => find_leaves(sub, name, path, out),
            _ if k == name => out.push(path.join(".")),
            _ => {}
        }
        path.pop();
    }
}

//! Reading a TOML file: at most [`crate::limits::MAX_CONFIG_BYTES`], a scene's
//! overrides merged in, and serde's errors said with the file, line, field and
//! the numbers a field allows.

use super::error::ConfigError;
use std::io::Read;
use std::path::Path;

/// Values a scene file overrides in a species or site file, and where they are
/// written, so that an error they cause names the scene file.
#[derive(Clone, Copy, Debug)]
pub struct Overrides<'a> {
    /// The scene file that holds them.
    pub file: &'a Path,
    /// Their table in that file, e.g. `species_overrides.coho`.
    pub section: &'a str,
    pub table: &'a toml::Table,
}

impl Overrides<'_> {
    /// Whether the overrides set `field` (`a.b.c`, `a[1]`) or a table above it.
    fn hold(&self, field: &str) -> bool {
        let mut table = self.table;
        for key in field.split('.') {
            let key = key.split('[').next().unwrap_or(key);
            match table.get(key) {
                Some(toml::Value::Table(t)) => table = t,
                Some(_) => return true,
                None => return false,
            }
        }
        true
    }

    /// Point an error of the file at `base` (merged with these overrides) at the
    /// scene file when an override caused it: the field it names is overridden,
    /// or `base` alone passes. `loads(key)` says whether `base` with only the
    /// override `key` (`None`: none) loads; the first key that breaks it is named.
    fn blame(
        &self,
        e: ConfigError,
        base: &Path,
        loads: impl Fn(Option<&str>) -> bool,
    ) -> ConfigError {
        let in_scene = |field: &str| format!("{}.{field}", self.section);
        match e {
            ConfigError::Invalid { field, message, .. } if self.hold(&field) => {
                ConfigError::Invalid {
                    path: self.file.to_path_buf(),
                    field: in_scene(&field),
                    message,
                }
            }
            ConfigError::Limit {
                field,
                value,
                above,
                limit,
                ..
            } if self.hold(&field) => ConfigError::Limit {
                path: self.file.to_path_buf(),
                field: in_scene(&field),
                value,
                above,
                limit,
            },
            e @ (ConfigError::Io { .. }
            | ConfigError::Unknown { .. }
            | ConfigError::NotAFile { .. }
            | ConfigError::NoRoot { .. }) => e,
            e if loads(None) => ConfigError::Invalid {
                path: self.file.to_path_buf(),
                field: match self.table.keys().find(|k| !loads(Some(k))) {
                    Some(key) => in_scene(key),
                    None => self.section.to_string(),
                },
                message: format!("{} (applied to {})", e.detail(), base.display()),
            },
            e => e,
        }
    }
}

/// Read and deserialize a TOML file of at most [`crate::limits::MAX_CONFIG_BYTES`];
/// errors name the file, line and field.
pub fn read_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, ConfigError> {
    let io = |error| ConfigError::Io {
        path: path.to_path_buf(),
        error,
    };
    let max = crate::limits::MAX_CONFIG_BYTES;
    let mut bytes = Vec::new();
    // `take` rather than the file's length: a FIFO or /dev/zero has none.
    std::fs::File::open(path)
        .and_then(|f| f.take(max + 1).read_to_end(&mut bytes))
        .map_err(io)?;
    if bytes.len() as u64 > max {
        return Err(ConfigError::Parse {
            path: path.to_path_buf(),
            message: format!(
                "the file is larger than {max} bytes, the limit of a configuration file"
            ),
        });
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text ({e})"),
        ))
    })?;
    toml::from_str(&text).map_err(|e| ConfigError::Parse {
        path: path.to_path_buf(),
        message: match e.span() {
            Some(span) => {
                let before = &text[..text.floor_char_boundary(span.start)];
                let line = before.matches('\n').count() + 1;
                let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
                let field =
                    field_at(&text, span.start).map_or(String::new(), |f| format!(", field `{f}`"));
                format!(
                    "line {line}, column {column}{field}: {}",
                    plain(e.message())
                )
            }
            None => plain(e.message()),
        },
    })
}

/// The dotted name of the `key = value` on the line holding byte `at` of a
/// TOML `text`, under its last table header: `group[1].count`. `None` when
/// that line holds no `key =` (a value continued from an earlier line).
fn field_at(text: &str, at: usize) -> Option<String> {
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let line = text[start..].lines().next()?;
    let key = line.split_once('=')?.0.trim();
    let bare = |k: &str| {
        !k.is_empty()
            && k.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
    };
    if !bare(key) {
        return None;
    }
    let headers = text[..start]
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with('['));
    let table = match headers.clone().next_back() {
        None => return Some(key.to_string()),
        Some(h) => h.split('#').next().unwrap_or(h).trim(),
    };
    Some(
        match table.strip_prefix("[[").and_then(|t| t.strip_suffix("]]")) {
            Some(name) => {
                let index = headers
                    .filter(|h| h.starts_with(&format!("[[{name}]]")))
                    .count()
                    - 1;
                format!("{}[{index}].{key}", name.trim())
            }
            None => format!("{}.{key}", table.trim_matches(['[', ']']).trim()),
        },
    )
}

/// serde's message with its Rust type names said as the numbers they allow:
/// "expected usize" becomes "expected a whole number ≥ 0".
fn plain(message: &str) -> String {
    let mut m = message.to_string();
    for (rust, allowed) in [
        ("usize", "a whole number ≥ 0"),
        ("u64", "a whole number ≥ 0"),
        ("u32", "a whole number from 0 to 4294967295"),
        ("u16", "a whole number from 0 to 65535"),
        ("u8", "a whole number from 0 to 255"),
        ("f32", "a number"),
        ("f64", "a number"),
    ] {
        m = m.replace(&format!("expected {rust}"), &format!("expected {allowed}"));
    }
    m
}

fn from_table<T: serde::de::DeserializeOwned>(
    path: &Path,
    table: toml::Table,
) -> Result<T, ConfigError> {
    toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| ConfigError::Parse {
            path: path.to_path_buf(),
            message: plain(e.message()),
        })
}

/// Read the file at `path`, apply `overrides`, deserialize and `validate`;
/// an error the overrides cause names the scene file that holds them.
pub(super) fn load_with<T: serde::de::DeserializeOwned>(
    path: &Path,
    overrides: Option<Overrides>,
    validate: impl Fn(&T, &Path) -> Result<(), ConfigError>,
) -> Result<T, ConfigError> {
    let base: toml::Table = read_toml(path)?;
    let load = |table: toml::Table| {
        let value: T = from_table(path, table)?;
        validate(&value, path).map(|()| value)
    };
    match overrides.filter(|o| !o.table.is_empty()) {
        None => load(base),
        Some(o) => {
            let mut merged = base.clone();
            merge(&mut merged, o.table);
            load(merged).map_err(|e| {
                // Does `base` load with no override (`None`) or only override `key`?
                let loads = |key: Option<&str>| {
                    let mut table = base.clone();
                    if let Some(k) = key {
                        let one: toml::Table = o
                            .table
                            .iter()
                            .filter(|(name, _)| *name == k)
                            .map(|(name, v)| (name.clone(), v.clone()))
                            .collect();
                        merge(&mut table, &one);
                    }
                    load(table).is_ok()
                };
                o.blame(e, path, loads)
            })
        }
    }
}

/// Overlay `over` onto `base`, recursing into tables.
fn merge(base: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_overrides_nested_values() {
        let mut base: toml::Table = toml::from_str("a = 1\n[t]\nx = 1\ny = 2").unwrap();
        let over: toml::Table = toml::from_str("[t]\ny = 3").unwrap();
        merge(&mut base, &over);
        assert_eq!(base["a"].as_integer(), Some(1));
        assert_eq!(base["t"]["x"].as_integer(), Some(1));
        assert_eq!(base["t"]["y"].as_integer(), Some(3));
    }
}

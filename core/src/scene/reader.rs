//! Typed, located access to a parsed TOML table.
//!
//! `toml_edit` keeps the byte span of every key and value; this layer reads
//! values with the types the scene format expects and, on any mismatch,
//! builds a [`SceneError`] pointing at the exact text. Numbers are converted
//! from their source text with [`parse_exact`], never through `f64`.

use toml_edit::{Item, Key, TableLike, Value};

use super::error::{SceneError, SceneErrorKind, Source};
use crate::math::decimal::{ParseDecimalError, parse_exact};
use crate::math::{Scalar, Vec3};

/// Result type of this module.
pub(super) type Result<T> = std::result::Result<T, SceneError>;

/// A table (a `[header]` table, an array-of-tables entry or an inline table)
/// together with where it is and how to name it in messages.
#[derive(Clone)]
pub(super) struct TableView<'a> {
    pub(super) src: Source<'a>,
    table: &'a dyn TableLike,
    /// Byte offset of the table's header or opening brace: where "missing
    /// key" errors point.
    pub(super) at: usize,
    /// Where in the scene this table is, e.g. `body "crate"`; prefixes every
    /// message. Empty for the root table.
    ctx: String,
    /// Key path from the context to this table (`rotation.` for a rotation
    /// table inside a body), so messages name nested keys fully.
    prefix: String,
}

/// One value of a table or array, located and named.
pub(super) struct Field<'a> {
    /// The value's full name for messages (`rotation.axis`, `points[3]`).
    pub(super) name: String,
    /// The value.
    pub(super) item: Node<'a>,
    /// Byte offset of the value (or of the key, if the value has no span).
    pub(super) at: usize,
}

/// A value in the document: a table entry (which may be a header table or
/// an array of tables) or an array element (always a plain value).
#[derive(Clone, Copy)]
pub(super) enum Node<'a> {
    /// An entry of a table.
    Item(&'a Item),
    /// An element of an array.
    Value(&'a Value),
}

impl<'a> Node<'a> {
    /// The plain value, unless this is a header table or array of tables.
    pub(super) fn as_value(self) -> Option<&'a Value> {
        match self {
            Node::Item(item) => item.as_value(),
            Node::Value(value) => Some(value),
        }
    }

    /// The table, whether written as a `[header]` or `{ inline }`.
    pub(super) fn as_table_like(self) -> Option<&'a dyn TableLike> {
        match self {
            Node::Item(item) => item.as_table_like(),
            Node::Value(Value::InlineTable(t)) => Some(t),
            Node::Value(_) => None,
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Node::Item(item) => describe_item(item),
            Node::Value(value) => describe_value(value),
        }
    }
}

impl<'a> TableView<'a> {
    /// The document's root table.
    pub(super) fn root(src: Source<'a>, table: &'a dyn TableLike) -> TableView<'a> {
        TableView {
            src,
            table,
            at: 0,
            ctx: String::new(),
            prefix: String::new(),
        }
    }

    /// Replaces the message context (`world`, `body "crate"`); key names
    /// in messages then start from this table.
    pub(super) fn set_context(&mut self, ctx: String) {
        self.ctx = ctx;
        self.prefix.clear();
    }

    /// The message context of this table.
    pub(super) fn context(&self) -> &str {
        &self.ctx
    }

    /// An error at byte `at`, with this table's context prefixed.
    pub(super) fn error(
        &self,
        at: usize,
        kind: SceneErrorKind,
        msg: impl AsRef<str>,
    ) -> SceneError {
        let message = if self.ctx.is_empty() {
            msg.as_ref().to_owned()
        } else {
            format!("{}: {}", self.ctx, msg.as_ref())
        };
        self.src.error(at, kind, message)
    }

    /// The full name of `key` for messages.
    pub(super) fn key_name(&self, key: &str) -> String {
        format!("{}{}", self.prefix, key)
    }

    /// The keys of this table with their spans, in file order.
    pub(super) fn keys(&self) -> Vec<(&'a str, usize)> {
        let table = self.table;
        table
            .iter()
            .map(|(k, _)| (k, key_offset(table.key(k)).unwrap_or(self.at)))
            .collect()
    }

    /// Every key/value pair, in file order.
    pub(super) fn fields(&self) -> Vec<Field<'a>> {
        let table = self.table;
        table
            .iter()
            .filter(|(_, item)| !item.is_none())
            .map(|(k, item)| self.field_of(k, item))
            .collect()
    }

    fn field_of(&self, key: &str, item: &'a Item) -> Field<'a> {
        let at = item_offset(item)
            .or_else(|| key_offset(self.table.key(key)))
            .unwrap_or(self.at);
        Field {
            name: self.key_name(key),
            item: Node::Item(item),
            at,
        }
    }

    /// Rejects every key not in `allowed`, naming the allowed ones and the
    /// closest match. `what` describes the table (`a sphere shape`).
    pub(super) fn check_keys(&self, allowed: &[&str], what: &str) -> Result<()> {
        for (key, at) in self.keys() {
            if allowed.contains(&key) {
                continue;
            }
            let hint = match closest(key, allowed) {
                Some(best) => format!("did you mean \"{best}\"? "),
                None => String::new(),
            };
            return Err(self.error(
                at,
                SceneErrorKind::UnknownKey,
                format!(
                    "unknown key \"{}\" in {what} ({hint}expected one of: {})",
                    self.key_name(key),
                    allowed.join(", ")
                ),
            ));
        }
        Ok(())
    }

    /// The value of `key`, if present.
    pub(super) fn get(&self, key: &str) -> Option<Field<'a>> {
        let item = self.table.get(key)?;
        if item.is_none() {
            return None;
        }
        Some(self.field_of(key, item))
    }

    /// The value of a required `key`; `expected` says what it should be
    /// (`a number, metres`).
    pub(super) fn require(&self, key: &str, expected: &str) -> Result<Field<'a>> {
        self.get(key).ok_or_else(|| {
            self.error(
                self.at,
                SceneErrorKind::MissingKey,
                format!(
                    "missing required key \"{}\" ({expected})",
                    self.key_name(key)
                ),
            )
        })
    }

    /// A sub-table (header table or inline table) as a view sharing this
    /// table's context, with its key path extended.
    pub(super) fn sub_table(&self, field: &Field<'a>, expected: &str) -> Result<TableView<'a>> {
        match field.item.as_table_like() {
            Some(table) => Ok(TableView {
                src: self.src,
                table,
                at: field.at,
                ctx: self.ctx.clone(),
                prefix: format!("{}.", field.name),
            }),
            None => Err(self.wrong_type(field, expected)),
        }
    }

    /// The tables of an array of tables, accepting both `[[key]]` headers
    /// and an array of inline tables, in file order.
    pub(super) fn table_array(
        &self,
        field: &Field<'a>,
        expected: &str,
    ) -> Result<Vec<TableView<'a>>> {
        let view = |table: &'a dyn TableLike, at: usize| TableView {
            src: self.src,
            table,
            at,
            ctx: self.ctx.clone(),
            prefix: String::new(),
        };
        match field.item {
            Node::Item(Item::ArrayOfTables(array)) => Ok(array
                .iter()
                .map(|t| view(t, t.span().map_or(field.at, |s| s.start)))
                .collect()),
            Node::Item(Item::Value(Value::Array(array))) => array
                .iter()
                .map(|v| match v {
                    Value::InlineTable(t) => Ok(view(t, value_offset(v).unwrap_or(field.at))),
                    other => Err(self.error(
                        value_offset(other).unwrap_or(field.at),
                        SceneErrorKind::WrongType,
                        format!(
                            "each element of {} must be a table ({expected}), found {}",
                            field.name,
                            describe_value(other)
                        ),
                    )),
                })
                .collect(),
            _ => Err(self.wrong_type(field, expected)),
        }
    }

    /// The error for a value of the wrong type.
    pub(super) fn wrong_type(&self, field: &Field<'_>, expected: &str) -> SceneError {
        self.error(
            field.at,
            SceneErrorKind::WrongType,
            format!(
                "{} must be {expected}, found {}",
                field.name,
                field.item.describe()
            ),
        )
    }

    /// The error for a value outside its range; `raw` is the value as
    /// written.
    pub(super) fn out_of_range(&self, at: usize, name: &str, rule: &str, raw: &str) -> SceneError {
        self.error(
            at,
            SceneErrorKind::OutOfRange,
            format!("{name} must be {rule}, found {raw}"),
        )
    }

    /// The source text of a value (for messages), or its display form.
    pub(super) fn raw(&self, value: &Value) -> String {
        match self.src.slice(value.span()) {
            Some(text) => text.trim().to_owned(),
            None => value.to_string().trim().to_owned(),
        }
    }

    // ---- typed readers ----

    /// A string value.
    pub(super) fn string(&self, field: &Field<'a>) -> Result<&'a str> {
        match field.item.as_value() {
            Some(Value::String(s)) => Ok(s.value().as_str()),
            _ => Err(self.wrong_type(field, "a string")),
        }
    }

    /// A boolean value.
    pub(super) fn boolean(&self, field: &Field<'a>) -> Result<bool> {
        match field.item.as_value() {
            Some(Value::Boolean(b)) => Ok(*b.value()),
            _ => Err(self.wrong_type(field, "true or false")),
        }
    }

    /// An integer value in `lo..=hi`; `rule` describes the range for the
    /// message.
    pub(super) fn integer(&self, field: &Field<'a>, lo: i64, hi: i64, rule: &str) -> Result<i64> {
        match field.item.as_value() {
            Some(v @ Value::Integer(i)) => {
                let n = *i.value();
                if n < lo || n > hi {
                    Err(self.out_of_range(field.at, &field.name, rule, &self.raw(v)))
                } else {
                    Ok(n)
                }
            }
            _ => Err(self.wrong_type(field, &format!("an integer ({rule})"))),
        }
    }

    /// A number, converted exactly.
    pub(super) fn scalar(&self, field: &Field<'a>) -> Result<Scalar> {
        match field.item.as_value() {
            Some(v) => self.scalar_value(v, &field.name, field.at),
            None => Err(self.wrong_type(field, "a number")),
        }
    }

    /// A number that must satisfy `ok`; `rule` describes the range.
    pub(super) fn scalar_where(
        &self,
        field: &Field<'a>,
        ok: impl Fn(Scalar) -> bool,
        rule: &str,
    ) -> Result<Scalar> {
        let v = self.scalar(field)?;
        if ok(v) {
            Ok(v)
        } else {
            let raw = field
                .item
                .as_value()
                .map_or_else(|| v.to_string(), |value| self.raw(value));
            Err(self.out_of_range(field.at, &field.name, rule, &raw))
        }
    }

    /// Converts one TOML value to a [`Scalar`] exactly. Integers convert
    /// from their value (they may be written in hex); floats from their
    /// source text with [`parse_exact`], so `0.1` becomes the Q32.32 value
    /// nearest to one tenth, not the one nearest to the `f64` nearest to it.
    pub(super) fn scalar_value(&self, value: &Value, name: &str, at: usize) -> Result<Scalar> {
        let at = value_offset(value).unwrap_or(at);
        match value {
            Value::Integer(i) => match i32::try_from(*i.value()) {
                Ok(n) => Ok(Scalar::from_int(n)),
                Err(_) => Err(self.error(
                    at,
                    SceneErrorKind::BadNumber,
                    format!(
                        "{name} = {} is outside the fixed-point range ±2147483648",
                        self.raw(value)
                    ),
                )),
            },
            Value::Float(_) => {
                let Some(text) = self.src.slice(value.span()) else {
                    return Err(self.error(
                        at,
                        SceneErrorKind::BadNumber,
                        format!("{name}: the number's source text is unavailable"),
                    ));
                };
                let text = text.trim();
                let lower = text.to_ascii_lowercase();
                if lower.contains("inf") || lower.contains("nan") {
                    return Err(self.error(
                        at,
                        SceneErrorKind::BadNumber,
                        format!(
                            "{name} must be a finite number, found {text} (inf and nan are not allowed)"
                        ),
                    ));
                }
                let value = parse_exact(text).map_err(|e| {
                    let why = match e {
                        ParseDecimalError::OutOfRange => {
                            "is outside the fixed-point range ±2147483648".to_owned()
                        }
                        ParseDecimalError::TooLong => "has too many digits".to_owned(),
                        other => format!("is not a decimal number ({other})"),
                    };
                    self.error(
                        at,
                        SceneErrorKind::BadNumber,
                        format!("{name} = {text} {why}"),
                    )
                })?;
                // A non-zero literal below half the resolution would become
                // 0 without a word: a radius, a mass or a speed the author
                // did not mean.
                let mantissa = text.split(['e', 'E']).next().unwrap_or(text);
                if value.is_zero() && mantissa.bytes().any(|c| matches!(c, b'1'..=b'9')) {
                    return Err(self.error(
                        at,
                        SceneErrorKind::BadNumber,
                        format!(
                            "{name} = {text} rounds to 0: numbers are fixed point with steps of 2^-32 (about 2.3e-10); write 0 or a larger value"
                        ),
                    ));
                }
                Ok(value)
            }
            other => Err(self.error(
                at,
                SceneErrorKind::WrongType,
                format!("{name} must be a number, found {}", describe_value(other)),
            )),
        }
    }

    /// An array of exactly `N` numbers; `form` names the components for the
    /// message (`[x, y, z]`).
    pub(super) fn scalars<const N: usize>(
        &self,
        field: &Field<'a>,
        form: &str,
    ) -> Result<[Scalar; N]> {
        let expected = format!("an array of {N} numbers {form}");
        let array = match field.item.as_value() {
            Some(Value::Array(a)) => a,
            _ => return Err(self.wrong_type(field, &expected)),
        };
        if array.len() != N {
            return Err(self.error(
                field.at,
                SceneErrorKind::WrongType,
                format!(
                    "{} must be {expected}, found {} element{}",
                    field.name,
                    array.len(),
                    if array.len() == 1 { "" } else { "s" }
                ),
            ));
        }
        let mut out = [Scalar::ZERO; N];
        for (i, (slot, value)) in out.iter_mut().zip(array.iter()).enumerate() {
            *slot = self.scalar_value(value, &format!("{}[{i}]", field.name), field.at)?;
        }
        Ok(out)
    }

    /// A 3-vector written `[x, y, z]`.
    pub(super) fn vec3(&self, field: &Field<'a>) -> Result<Vec3> {
        let [x, y, z] = self.scalars::<3>(field, "[x, y, z]")?;
        Ok(Vec3::new(x, y, z))
    }

    /// An array of `[x, y, z]` points; `min..=max` elements.
    pub(super) fn vec3_list(&self, field: &Field<'a>, min: usize, max: usize) -> Result<Vec<Vec3>> {
        self.array(field, "an array of [x, y, z] points", min, max)?
            .iter()
            .map(|element| self.vec3(element))
            .collect()
    }

    /// The elements of an array value, located and named `name[i]`, checking
    /// the count is in `min..=max`.
    pub(super) fn array(
        &self,
        field: &Field<'a>,
        expected: &str,
        min: usize,
        max: usize,
    ) -> Result<Vec<Field<'a>>> {
        let array = match field.item.as_value() {
            Some(Value::Array(a)) => a,
            _ => return Err(self.wrong_type(field, expected)),
        };
        if array.len() < min || array.len() > max {
            return Err(self.error(
                field.at,
                SceneErrorKind::OutOfRange,
                format!(
                    "{} must have {min} to {max} elements, found {}",
                    field.name,
                    array.len()
                ),
            ));
        }
        Ok(array
            .iter()
            .enumerate()
            .map(|(i, v)| Field {
                name: format!("{}[{i}]", field.name),
                item: Node::Value(v),
                at: value_offset(v).unwrap_or(field.at),
            })
            .collect())
    }
}

/// Byte offset where a key starts.
fn key_offset(key: Option<&Key>) -> Option<usize> {
    key.and_then(|k| k.span()).map(|s| s.start)
}

/// Byte offset where a value starts.
pub(super) fn value_offset(value: &Value) -> Option<usize> {
    value.span().map(|s| s.start)
}

/// Byte offset where an item starts.
pub(super) fn item_offset(item: &Item) -> Option<usize> {
    match item {
        Item::Value(v) => v.span(),
        Item::Table(t) => t.span(),
        Item::ArrayOfTables(a) => a.span(),
        Item::None => None,
    }
    .map(|s| s.start)
}

/// "a string", "an integer", ... for messages.
pub(super) fn describe_value(value: &Value) -> &'static str {
    match value {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a float",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a date-time",
        Value::Array(_) => "an array",
        Value::InlineTable(_) => "a table",
    }
}

/// Like [`describe_value`], for any item.
pub(super) fn describe_item(item: &Item) -> &'static str {
    match item {
        Item::Value(v) => describe_value(v),
        Item::Table(_) => "a table",
        Item::ArrayOfTables(_) => "an array of tables",
        Item::None => "nothing",
    }
}

/// The allowed key closest to `key` by edit distance, if it is close enough
/// to be a plausible typo (at most a third of the key's length, at least 1).
pub(super) fn closest<'k>(key: &str, allowed: &[&'k str]) -> Option<&'k str> {
    let limit = (key.chars().count() / 3).max(1);
    allowed
        .iter()
        .map(|a| (edit_distance(key, a), *a))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, a)| a)
}

/// Levenshtein distance between two short strings, by characters. Keys are
/// bounded by the input size; the row buffer is linear in `b`.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let above = row[j + 1];
            let cost = usize::from(ca != *cb);
            row[j + 1] = (above + 1).min(row[j] + 1).min(diagonal + cost);
            diagonal = above;
        }
    }
    row[b.len()]
}

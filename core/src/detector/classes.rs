//! The model's classes, read from its metadata: its class names are the
//! tower types it tells apart (`A`-`D` for the demo's models, "lattice" or a
//! line's own design names for a user's, one `tower` class for a model that
//! does not tell types apart). Whether they are the landmark database's
//! types is checked where both are known (`landmarks::match_types`).
//!
//! Ultralytics writes `names` as a Python dict literal, `{0: 'A', 1: 'B'}`;
//! other exporters write a JSON list or object.

use towernav_protocol::TowerType;

use super::decode::MAX_CLASSES;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClassError {
    #[error(
        "the model has no `names` metadata; export it with Ultralytics (which writes the class names) or add them"
    )]
    Missing,
    #[error("the model's `names` metadata is not a class list ({reason}): {text:?}")]
    Unreadable { text: String, reason: String },
    #[error(
        "the model has {} classes ({}); a tower detector has 1 to {MAX_CLASSES} tower types",
        found.len(), preview(found)
    )]
    TooMany { found: Vec<String> },
    #[error("the model's class {index} is not a tower type name: {reason}")]
    BadName { index: usize, reason: String },
    #[error("the model names class {name:?} twice")]
    Duplicate { name: String },
}

/// The first few names, for messages about models with many classes.
fn preview(names: &[String]) -> String {
    let shown: Vec<&str> = names.iter().take(6).map(String::as_str).collect();
    let more = names.len().saturating_sub(shown.len());
    if more > 0 {
        format!("{}, and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

/// Class index to tower type.
#[derive(Debug, Clone, PartialEq)]
pub struct ClassMap {
    pub names: Vec<String>,
    types: Vec<TowerType>,
}

impl ClassMap {
    /// Classes from the `names` metadata value: 1 to `MAX_CLASSES` distinct type names.
    pub fn from_metadata(names: Option<&str>) -> Result<Self, ClassError> {
        let text = names.ok_or(ClassError::Missing)?;
        let names = parse_names(text).map_err(|reason| ClassError::Unreadable {
            text: text.to_string(),
            reason,
        })?;
        if names.is_empty() || names.len() > MAX_CLASSES {
            return Err(ClassError::TooMany { found: names });
        }
        let mut types: Vec<TowerType> = Vec::with_capacity(names.len());
        for (index, name) in names.iter().enumerate() {
            let t = TowerType::new(name).map_err(|e| ClassError::BadName {
                index,
                reason: e.to_string(),
            })?;
            if types.contains(&t) {
                return Err(ClassError::Duplicate { name: name.clone() });
            }
            types.push(t);
        }
        Ok(Self { names, types })
    }

    pub fn len(&self) -> usize {
        self.types.len()
    }

    pub fn is_empty(&self) -> bool {
        self.types.is_empty()
    }

    pub fn tower_type(&self, class: usize) -> Option<TowerType> {
        self.types.get(class).copied()
    }

    /// The types, in class order.
    pub fn types(&self) -> &[TowerType] {
        &self.types
    }
}

/// Names in class order from `{0: 'A', 1: 'B'}`, `{"0": "A"}` or `["A", "B"]`.
pub fn parse_names(text: &str) -> Result<Vec<String>, String> {
    let t = text.trim();
    let (open, close, keyed) = match t.chars().next() {
        Some('{') => ('{', '}', true),
        Some('[') => ('[', ']', false),
        _ => return Err("expected a dict or a list".into()),
    };
    let body = t
        .strip_prefix(open)
        .and_then(|b| b.strip_suffix(close))
        .ok_or_else(|| format!("unbalanced {open}{close}"))?;
    let mut chars = body.chars().peekable();
    let mut entries: Vec<(usize, String)> = Vec::new();
    loop {
        skip_space(&mut chars);
        if chars.peek().is_none() {
            break;
        }
        let index = if keyed {
            let key = read_token(&mut chars)?;
            let key = key
                .trim_matches(|c| c == '"' || c == '\'')
                .parse::<usize>()
                .map_err(|_| format!("class key {key:?} is not a number"))?;
            skip_space(&mut chars);
            if chars.next() != Some(':') {
                return Err(format!("expected ':' after key {key}"));
            }
            skip_space(&mut chars);
            key
        } else {
            entries.len()
        };
        let name = read_quoted(&mut chars)?;
        entries.push((index, name));
        skip_space(&mut chars);
        match chars.next() {
            Some(',') | None => {}
            Some(c) => return Err(format!("unexpected {c:?} after a name")),
        }
    }
    entries.sort_by_key(|(i, _)| *i);
    if entries.iter().enumerate().any(|(k, (i, _))| k != *i) {
        return Err("class indices are not 0..N without gaps".into());
    }
    Ok(entries.into_iter().map(|(_, n)| n).collect())
}

type Chars<'a> = std::iter::Peekable<std::str::Chars<'a>>;

fn skip_space(chars: &mut Chars<'_>) {
    while chars.peek().is_some_and(|c| c.is_whitespace()) {
        chars.next();
    }
}

fn read_token(chars: &mut Chars<'_>) -> Result<String, String> {
    if matches!(chars.peek(), Some('"' | '\'')) {
        return read_quoted(chars);
    }
    let mut s = String::new();
    while let Some(&c) = chars.peek() {
        if c == ':' || c.is_whitespace() {
            break;
        }
        s.push(c);
        chars.next();
    }
    Ok(s)
}

fn read_quoted(chars: &mut Chars<'_>) -> Result<String, String> {
    let quote = match chars.next() {
        Some(q @ ('"' | '\'')) => q,
        other => return Err(format!("expected a quoted name, found {other:?}")),
    };
    let mut s = String::new();
    loop {
        match chars.next() {
            Some('\\') => s.push(chars.next().ok_or("unfinished escape")?),
            Some(c) if c == quote => return Ok(s),
            Some(c) => s.push(c),
            None => return Err("unterminated name".into()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn ultralytics_python_dict_and_json_forms_parse() {
        let want = vec!["A", "B", "C", "D"];
        assert_eq!(
            parse_names("{0: 'A', 1: 'B', 2: 'C', 3: 'D'}").expect("dict"),
            want
        );
        assert_eq!(
            parse_names(r#"{"1": "B", "0": "A", "3": "D", "2": "C"}"#).expect("json"),
            want
        );
        assert_eq!(parse_names(r#"["A","B","C","D"]"#).expect("list"), want);
        assert_eq!(
            parse_names("{0: 'it\\'s, odd'}").expect("escape"),
            vec!["it's, odd"]
        );
    }

    #[test]
    fn any_tower_type_names_are_classes_and_bad_lists_are_refused() {
        let one = ClassMap::from_metadata(Some("{0: 'tower'}")).expect("one class");
        assert_eq!(one.types(), [TowerType::new("tower").expect("name")]);
        let own = ClassMap::from_metadata(Some("['lattice', 'tubular', 'portal']")).expect("own");
        assert_eq!(own.tower_type(2).map(|t| t.as_str()), Some("portal"));
        let many: Vec<String> = (0..80).map(|i| format!("'c{i}'")).collect();
        let err = ClassMap::from_metadata(Some(&format!("[{}]", many.join(", "))))
            .expect_err("coco-sized")
            .to_string();
        assert!(
            err.contains("80 classes") && err.contains("tower types"),
            "{err}"
        );
        assert!(matches!(
            ClassMap::from_metadata(Some("['A', 'a']")),
            Err(ClassError::Duplicate { .. })
        ));
        assert!(matches!(
            ClassMap::from_metadata(Some("['ok', 'no,way']")),
            Err(ClassError::BadName { index: 1, .. })
        ));
        assert_eq!(ClassMap::from_metadata(None), Err(ClassError::Missing));
        assert!(matches!(
            ClassMap::from_metadata(Some("{0: 'A', 2: 'B'}")),
            Err(ClassError::Unreadable { .. })
        ));
        let ok = ClassMap::from_metadata(Some("{0: 'A', 1: 'B', 2: 'C', 3: 'D'}")).expect("ok");
        assert_eq!(ok.tower_type(2), Some(TowerType::C));
        assert_eq!(ok.tower_type(4), None);
    }

    proptest! {
        #[test]
        fn any_text_gives_names_or_an_error_never_a_panic(text in ".{0,60}") {
            let _ = parse_names(&text);
        }

        #[test]
        fn written_dicts_read_back(names in proptest::collection::vec("[a-zA-Z0-9 ,:'\"]{1,8}", 1..6)) {
            let body: Vec<String> = names
                .iter()
                .enumerate()
                .map(|(i, n)| format!("{i}: '{}'", n.replace('\\', "\\\\").replace('\'', "\\'")))
                .collect();
            let text = format!("{{{}}}", body.join(", "));
            prop_assert_eq!(parse_names(&text).expect("written"), names);
        }
    }
}

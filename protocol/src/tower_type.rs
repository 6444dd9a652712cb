//! Tower types as text: the names a line's owner gives its designs
//! ("lattice", "portal", "N2-45"), a model's class names, or the rendered
//! worlds' A to D. Each distinct name is stored once for the life of the
//! process (at most [`MAX_TYPE_NAMES`] of them), so a type is a `Copy`
//! handle that compares by its text. Names compare ignoring ASCII case: the
//! first spelling seen is the one kept.

use std::sync::Mutex;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Distinct type names one process will hold; a peer cannot grow it past this.
pub const MAX_TYPE_NAMES: usize = 1024;
/// Longest type name, in characters.
pub const MAX_TYPE_NAME_CHARS: usize = 40;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TowerType(&'static str);

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TowerTypeError {
    #[error("a tower type needs a name")]
    Empty,
    #[error("tower type {0:?} is longer than {MAX_TYPE_NAME_CHARS} characters")]
    TooLong(String),
    #[error("tower type {name:?} holds {bad:?}; use letters, digits, spaces and - _ . / + ( )")]
    BadCharacter { name: String, bad: char },
    #[error("tower type {0:?} would be past the {MAX_TYPE_NAMES} distinct types one process holds")]
    TooMany(String),
}

static NAMES: Mutex<Vec<&'static str>> = Mutex::new(Vec::new());

impl TowerType {
    /// The rendered worlds' four designs, and the classes of the demo's models.
    pub const A: TowerType = TowerType("A");
    pub const B: TowerType = TowerType("B");
    pub const C: TowerType = TowerType("C");
    pub const D: TowerType = TowerType("D");
    pub const ALL: [TowerType; 4] = [Self::A, Self::B, Self::C, Self::D];

    /// The type named `name` (trimmed), checked.
    pub fn new(name: &str) -> Result<Self, TowerTypeError> {
        let name = name.trim();
        if name.is_empty() {
            return Err(TowerTypeError::Empty);
        }
        if name.chars().count() > MAX_TYPE_NAME_CHARS {
            return Err(TowerTypeError::TooLong(name.to_string()));
        }
        if let Some(bad) = name
            .chars()
            .find(|c| !(c.is_alphanumeric() || " -_./+()".contains(*c)))
        {
            return Err(TowerTypeError::BadCharacter {
                name: name.to_string(),
                bad,
            });
        }
        if let Some(t) = Self::ALL.iter().find(|t| t.0.eq_ignore_ascii_case(name)) {
            return Ok(*t);
        }
        // A poisoned lock still holds a valid list: names are only ever pushed.
        let mut names = NAMES.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(known) = names.iter().find(|n| n.eq_ignore_ascii_case(name)) {
            return Ok(Self(known));
        }
        if names.len() >= MAX_TYPE_NAMES {
            return Err(TowerTypeError::TooMany(name.to_string()));
        }
        let kept: &'static str = Box::leak(name.to_string().into_boxed_str());
        names.push(kept);
        Ok(Self(kept))
    }

    pub fn as_str(self) -> &'static str {
        self.0
    }

    /// Position among the rendered designs A to D, if it is one.
    pub fn rendered_index(self) -> Option<usize> {
        Self::ALL.iter().position(|t| *t == self)
    }
}

impl std::str::FromStr for TowerType {
    type Err = TowerTypeError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::new(s)
    }
}

impl std::fmt::Display for TowerType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

impl Serialize for TowerType {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.0)
    }
}

impl<'de> Deserialize<'de> for TowerType {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = std::borrow::Cow::<'de, str>::deserialize(d)?;
        Self::new(&name).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    #[test]
    fn names_are_text_compared_ignoring_case() {
        let lattice = TowerType::new(" Lattice 2x ").expect("valid");
        assert_eq!(lattice.as_str(), "Lattice 2x");
        assert_eq!(TowerType::new("LATTICE 2X").expect("valid"), lattice);
        assert_eq!(TowerType::new("a").expect("valid"), TowerType::A);
        assert_eq!(TowerType::A.rendered_index(), Some(0));
        assert_eq!(lattice.rendered_index(), None);
        assert!(matches!(TowerType::new("  "), Err(TowerTypeError::Empty)));
        assert!(matches!(
            TowerType::new("a,b"),
            Err(TowerTypeError::BadCharacter { bad: ',', .. })
        ));
        assert!(matches!(
            TowerType::new(&"x".repeat(41)),
            Err(TowerTypeError::TooLong(_))
        ));
    }

    #[test]
    fn types_travel_as_their_names() {
        let t = TowerType::new("portal").expect("valid");
        let json = serde_json::to_string(&t).expect("json");
        assert_eq!(json, "\"portal\"");
        let back: TowerType = serde_json::from_str(&json).expect("back");
        assert_eq!(back, t);
        let bad: Result<TowerType, _> = serde_json::from_str("\"no\\nline\"");
        assert!(bad.is_err());
    }

    proptest! {
        #[test]
        fn any_accepted_name_reads_back_as_itself(name in "[A-Za-z0-9][A-Za-z0-9 _./+()-]{0,30}") {
            let t = TowerType::new(&name).expect("valid");
            prop_assert!(t.as_str().eq_ignore_ascii_case(name.trim()));
            prop_assert_eq!(t.to_string().parse::<TowerType>().expect("parses"), t);
        }
    }
}

//! Fleet and UAV identifiers, restricted to what a Zenoh key chunk can hold.

use serde::{Deserialize, Serialize};
use std::fmt;

/// A fleet or UAV id: 1 to 64 of `A-Z a-z 0-9 _ -`.
///
/// Zenoh reserves `/ * $ ? # @` and whitespace in keys; rather than escape them we refuse them.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub struct NodeId(String);

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum IdError {
    #[error("id is empty")]
    Empty,
    #[error("id {0:?} is longer than 64 characters")]
    TooLong(String),
    #[error("id {id:?} holds {bad:?}, which a Zenoh key cannot carry (allowed: A-Z a-z 0-9 _ -)")]
    BadChar { id: String, bad: char },
}

impl NodeId {
    pub fn new(id: impl Into<String>) -> Result<Self, IdError> {
        let id = id.into();
        if id.is_empty() {
            return Err(IdError::Empty);
        }
        if id.chars().count() > 64 {
            return Err(IdError::TooLong(id));
        }
        if let Some(bad) = id
            .chars()
            .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-'))
        {
            return Err(IdError::BadChar { id, bad });
        }
        Ok(Self(id))
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl TryFrom<String> for NodeId {
    type Error = IdError;
    fn try_from(value: String) -> Result<Self, Self::Error> {
        Self::new(value)
    }
}

impl From<NodeId> for String {
    fn from(value: NodeId) -> Self {
        value.0
    }
}

impl std::str::FromStr for NodeId {
    type Err = IdError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::new(s)
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn key_hostile_characters_are_refused() {
        for bad in ["a/b", "uav*", "x y", "$a", "a?b", "a#b", "a@b", ""] {
            assert!(NodeId::new(bad).is_err(), "{bad:?} must be refused");
        }
        assert!(NodeId::new("uav-01_A").is_ok());
        assert!(matches!(
            NodeId::new("a".repeat(65)),
            Err(IdError::TooLong(_))
        ));
    }

    proptest! {
        #[test]
        fn valid_ids_survive_json(id in "[A-Za-z0-9_-]{1,64}") {
            let node = NodeId::new(id.clone()).expect("valid");
            let json = serde_json::to_string(&node).expect("serialize");
            let back: NodeId = serde_json::from_str(&json).expect("deserialize");
            prop_assert_eq!(back.as_str(), id.as_str());
        }
    }
}

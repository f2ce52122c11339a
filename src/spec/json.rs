//! The one reader of JSON inputs (specs, eval bodies, points and field
//! files, scenes): exactly one JSON document, errors naming the JSON path
//! (`$` for the document), and nothing but whitespace after it.

use super::SpecError;
use serde::de::DeserializeOwned;

/// Parse one JSON document from `bytes` into `T`. Errors carry the JSON path
/// of the problem; anything but whitespace after the document is refused
/// with "trailing data after the JSON document at line L column C".
pub fn from_slice<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, SpecError> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value: T = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = e.path().to_string();
        SpecError::new(
            if path == "." { "$".into() } else { path },
            e.inner().to_string(),
        )
    })?;
    de.end().map_err(|e| trailing(&e))?;
    Ok(value)
}

/// [`from_slice`] of a string.
pub fn from_str<T: DeserializeOwned>(text: &str) -> Result<T, SpecError> {
    from_slice(text.as_bytes())
}

/// The error of [`serde_json::Deserializer::end`]: where the trailing data
/// starts (1-based line and column, as serde_json counts them).
fn trailing(e: &serde_json::Error) -> SpecError {
    SpecError::new(
        "$",
        format!(
            "trailing data after the JSON document at line {} column {}",
            e.line(),
            e.column()
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    struct Doc {
        #[allow(dead_code)]
        a: u32,
    }

    #[test]
    fn whitespace_after_the_document_is_fine() {
        assert!(from_str::<Doc>("  {\"a\": 1} \n\t \r\n").is_ok());
    }

    #[test]
    fn trailing_data_is_refused_where_it_starts() {
        // The second document starts on line 2, column 3 (1-based).
        let e = from_str::<Doc>("{\"a\": 1}\n  {\"a\": 2}").unwrap_err();
        assert_eq!(e.path, "$");
        assert_eq!(
            e.message,
            "trailing data after the JSON document at line 2 column 3"
        );
        let e = from_str::<Doc>("{\"a\": 1} xx").unwrap_err();
        assert_eq!(
            e.message,
            "trailing data after the JSON document at line 1 column 10"
        );
    }
}

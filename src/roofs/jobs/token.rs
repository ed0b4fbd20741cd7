//! Names clients hold for server-side work (classification batches, adaptations): 128 random
//! bits, so no client can guess another's.

use super::job::JobError;

/// 128 random bits as 32 lowercase hex digits.
pub fn random_token() -> Result<String, JobError> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| JobError::Corrupt(format!("no randomness: {e}")))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Whether `text` has the form of a token (it may still name nothing).
pub fn is_token(text: &str) -> bool {
    text.len() == 32
        && text
            .bytes()
            .all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_are_32_hex_digits_and_differ() {
        let (a, b) = (random_token().unwrap(), random_token().unwrap());
        assert!(is_token(&a) && is_token(&b));
        assert_ne!(a, b);
        assert!(!is_token("1"));
        assert!(!is_token(&a.to_uppercase()));
        assert!(!is_token(&format!("{a}0")));
    }
}

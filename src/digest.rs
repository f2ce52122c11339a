//! SHA-256 (FIPS 180-4) digests and their lowercase hex spelling: the one
//! place that hashes bytes, for content addresses (result ids,
//! `plan::id`), blob names (`storage::blobs`), the checksum of a table
//! file (`brdf::format`), HTTP ETags and the `sha256_of_file` of the
//! command line's summaries.

use sha2::{Digest, Sha256};

/// Bytes of a SHA-256 digest.
pub const SHA256_LEN: usize = 32;

/// The SHA-256 of the concatenation of `parts` (hashed in order, without
/// copying them into one buffer).
pub fn sha256_of(parts: &[&[u8]]) -> [u8; SHA256_LEN] {
    let mut h = Sha256::new();
    for p in parts {
        h.update(p);
    }
    h.finalize().into()
}

/// The SHA-256 of a byte string.
pub fn sha256(bytes: &[u8]) -> [u8; SHA256_LEN] {
    sha256_of(&[bytes])
}

/// Lowercase hex of a byte string.
pub fn hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        s.push(DIGITS[(b >> 4) as usize] as char);
        s.push(DIGITS[(b & 15) as usize] as char);
    }
    s
}

/// Lowercase hex SHA-256 of a byte string (64 digits).
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&sha256(bytes))
}

/// True for the lowercase hex spelling of a SHA-256 (64 digits `0-9a-f`),
/// the form of every id and blob name.
pub fn is_sha256_hex(s: &str) -> bool {
    s.len() == 2 * SHA256_LEN && s.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FIPS 180-4 test vectors (NIST CSRC examples).
    #[test]
    fn known_digests() {
        assert_eq!(
            sha256_hex(b""),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
        );
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn parts_hash_as_their_concatenation() {
        assert_eq!(sha256_of(&[b"ab", b"", b"c"]), sha256(b"abc"));
    }

    #[test]
    fn hex_and_its_check() {
        assert_eq!(hex(&[0x00, 0x0f, 0xa0, 0xff]), "000fa0ff");
        assert!(is_sha256_hex(&sha256_hex(b"x")));
        assert!(!is_sha256_hex(&sha256_hex(b"x").to_uppercase()));
        assert!(!is_sha256_hex("abc"));
        assert!(!is_sha256_hex(&"g".repeat(64)));
    }
}

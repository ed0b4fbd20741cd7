//! Stage 4 of the encoder: the GLB container (glTF 2.0 binary): a 12-byte header, the JSON chunk
//! padded with spaces and the BIN chunk padded with zeros, each to 4 bytes.

/// Wraps a JSON document and a binary buffer of `bin_len` bytes, which `write_bin` appends to
/// the output in place (no intermediate copy), into a GLB. An empty buffer gets no BIN chunk.
pub fn write_container_with(
    mut json: Vec<u8>,
    bin_len: usize,
    write_bin: impl FnOnce(&mut Vec<u8>),
) -> Vec<u8> {
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let padded = bin_len.next_multiple_of(4);
    let has_bin = bin_len > 0;
    let total = 12 + 8 + json.len() + if has_bin { 8 + padded } else { 0 };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if has_bin {
        out.extend_from_slice(&(padded as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        let start = out.len();
        write_bin(&mut out);
        debug_assert_eq!(
            out.len() - start,
            bin_len,
            "the binary buffer's announced length"
        );
        out.resize(start + padded, 0);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_are_padded_and_lengths_add_up() {
        let glb = write_container_with(b"{}".to_vec(), 5, |out| {
            out.extend_from_slice(&[1, 2, 3, 4, 5]);
        });
        // 12 header + 8 + 4 JSON ("{}  ") + 8 + 8 BIN (5 bytes + 3 zeros).
        assert_eq!(glb.len(), 40);
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()), 40);
        assert_eq!(&glb[20..24], b"{}  ");
        assert_eq!(&glb[28..32], b"BIN\0");
        assert_eq!(&glb[32..40], &[1, 2, 3, 4, 5, 0, 0, 0]);
        assert_eq!(write_container_with(b"{}".to_vec(), 0, |_| {}).len(), 24);
    }
}

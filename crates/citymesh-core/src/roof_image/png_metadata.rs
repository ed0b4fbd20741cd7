//! How many bytes of text metadata (`tEXt`, `zTXt`, `iTXt` chunks) a PNG carries, counted by
//! walking its chunk headers without decoding anything. citymesh reads no metadata; a PNG with
//! more than a little of it (a compressed chunk that would inflate to gigabytes, say) is refused
//! before it is decoded.

/// The 8-byte PNG signature.
const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// Most bytes of text chunks an accepted PNG may carry.
pub const MAX_PNG_TEXT_BYTES: usize = 64 * 1024;

/// Bytes of the text chunks of `bytes` when it is a PNG (chunks whose declared length runs past
/// the end count with the length declared); 0 for anything else.
pub fn png_text_bytes(bytes: &[u8]) -> usize {
    if !bytes.starts_with(&SIGNATURE) {
        return 0;
    }
    let mut at = SIGNATURE.len();
    let mut total = 0usize;
    while let Some(header) = bytes.get(at..at + 8) {
        let length = u32::from_be_bytes([header[0], header[1], header[2], header[3]]) as usize;
        if matches!(&header[4..8], b"tEXt" | b"zTXt" | b"iTXt") {
            total = total.saturating_add(length);
        }
        if &header[4..8] == b"IEND" {
            break;
        }
        // Length, type, data, CRC.
        at = at.saturating_add(12).saturating_add(length);
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        out.extend_from_slice(&[0, 0, 0, 0]);
        out
    }

    #[test]
    fn text_chunks_are_counted_and_nothing_else() {
        let mut png = SIGNATURE.to_vec();
        png.extend(chunk(b"IHDR", &[0; 13]));
        png.extend(chunk(b"tEXt", b"Comment\0hello"));
        png.extend(chunk(b"zTXt", &[7; 1000]));
        png.extend(chunk(b"IDAT", &[1; 50]));
        png.extend(chunk(b"IEND", &[]));
        assert_eq!(png_text_bytes(&png), 13 + 1000);
        // A declared length past the end counts as declared.
        let mut cut = SIGNATURE.to_vec();
        cut.extend_from_slice(&(u32::MAX).to_be_bytes());
        cut.extend_from_slice(b"iTXt");
        assert_eq!(png_text_bytes(&cut), u32::MAX as usize);
        assert_eq!(png_text_bytes(b"\xff\xd8\xff JPEG"), 0);
        assert_eq!(png_text_bytes(&SIGNATURE), 0);
    }
}

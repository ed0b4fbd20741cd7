//! Requests hyper refuses before the router sees them (a request target of 65,535 bytes or more,
//! more header lines than it parses, bytes that are not HTTP) get hyper's own answer, which has an
//! empty body. The connection recognises those answers as they are written and sends the same
//! status with the JSON error body every other error has.

/// hyper's empty answers that close the connection: status line prefix, code, detail.
const CANNED: [(&[u8], &str, &str); 3] = [
    (
        b"HTTP/1.1 414 ",
        "uri_too_long",
        "the request target is far over this server's limit (8 KiB): shorten the query",
    ),
    (
        b"HTTP/1.1 431 ",
        "headers_too_large",
        "the request has far more header lines or bytes than this server reads (100 lines, \
         32 KiB): send fewer or shorter headers",
    ),
    (
        b"HTTP/1.1 400 ",
        "bad_request",
        "the request is not valid HTTP/1.1",
    ),
];

/// The JSON-bodied answer to write instead of `head`, when `head` is one of hyper's empty
/// answers to a request it could not parse.
pub fn json_answer(head: &[u8]) -> Option<Vec<u8>> {
    let (prefix, code, detail) = CANNED.iter().find(|(p, _, _)| head.starts_with(p))?;
    let end = head.windows(4).position(|w| w == b"\r\n\r\n")?;
    let lower = head[..end].to_ascii_lowercase();
    let has = |needle: &[u8]| lower.windows(needle.len()).any(|w| w == needle);
    // Only hyper's own: no body, and the connection closes after it.
    if end + 4 != head.len() || !has(b"\r\ncontent-length: 0") || !has(b"\r\nconnection: close") {
        return None;
    }
    let status_line = &head[..head.windows(2).position(|w| w == b"\r\n")?];
    debug_assert!(status_line.starts_with(prefix));
    let body = format!(r#"{{"error":"{code}","detail":"{detail}"}}"#);
    let mut out = status_line.to_vec();
    out.extend_from_slice(
        format!(
            "\r\nconnection: close\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\r\n{body}",
            body.len()
        )
        .as_bytes(),
    );
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hyper_s_empty_answers_get_json_and_nothing_else_is_touched() {
        let head = b"HTTP/1.1 414 URI Too Long\r\nconnection: close\r\ncontent-length: 0\r\ndate: Tue, 01 Dec 2026 20:31:07 GMT\r\n\r\n";
        let out = String::from_utf8(json_answer(head).unwrap()).unwrap();
        assert!(out.starts_with("HTTP/1.1 414 URI Too Long\r\n"), "{out}");
        let (headers, body) = out.split_once("\r\n\r\n").unwrap();
        assert!(headers.contains(&format!("content-length: {}", body.len())));
        let json: serde_json::Value = serde_json::from_str(body).unwrap();
        assert_eq!(json["error"], "uri_too_long");
        // Our own answers (with a body) and ordinary ones pass untouched.
        assert!(json_answer(b"HTTP/1.1 414 URI Too Long\r\ncontent-type: application/json\r\ncontent-length: 20\r\n\r\n").is_none());
        assert!(
            json_answer(b"HTTP/1.1 200 OK\r\nconnection: close\r\ncontent-length: 0\r\n\r\n")
                .is_none()
        );
        assert!(json_answer(b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\n\r\n").is_none());
    }
}

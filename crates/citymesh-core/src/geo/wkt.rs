//! Polygons written as WKT (well-known text), as labelled image sets give footprints in pixels.

/// The rings of a WKT `POLYGON ((x y, ...), (x y, ...))`: outer ring first, then holes; at
/// most `max_vertices` points in all.
pub fn parse_wkt_polygon(text: &str, max_vertices: usize) -> Result<Vec<Vec<[f64; 2]>>, String> {
    let t = text.trim();
    let body = t
        .get(..7)
        .filter(|head| head.eq_ignore_ascii_case("POLYGON"))
        .map(|_| t[7..].trim())
        .ok_or("expected POLYGON ((x y, ...))")?;
    let inner = body
        .strip_prefix('(')
        .and_then(|b| b.strip_suffix(')'))
        .ok_or("expected the rings in parentheses")?;
    let mut rings = Vec::new();
    let mut vertices = 0;
    for part in inner.split(')') {
        let part = part.trim().trim_start_matches(',').trim();
        if part.is_empty() {
            continue;
        }
        let coords = part
            .strip_prefix('(')
            .ok_or("expected a ring in parentheses")?;
        let mut ring = Vec::new();
        for pair in coords.split(',') {
            let mut it = pair.split_whitespace();
            let (Some(x), Some(y)) = (it.next(), it.next()) else {
                return Err(format!("`{}` is not `x y`", pair.trim()));
            };
            let x: f64 = x.parse().map_err(|_| format!("`{x}` is not a number"))?;
            let y: f64 = y.parse().map_err(|_| format!("`{y}` is not a number"))?;
            if !x.is_finite() || !y.is_finite() {
                return Err("coordinates must be finite".into());
            }
            vertices += 1;
            if vertices > max_vertices {
                return Err(format!("more than {max_vertices} vertices"));
            }
            ring.push([x, y]);
        }
        if ring.len() < 3 {
            return Err("a ring needs at least 3 points".into());
        }
        rings.push(ring);
    }
    if rings.is_empty() {
        return Err("the polygon has no ring".into());
    }
    Ok(rings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polygon_with_a_hole_reads_as_two_rings() {
        let rings = parse_wkt_polygon(
            "POLYGON ((0 0, 10 0, 10 5.5, 0 5.5, 0 0), (1 1, 2 1, 2 2, 1 1))",
            100,
        )
        .unwrap();
        assert_eq!(rings.len(), 2);
        assert_eq!(rings[0][2], [10.0, 5.5]);
        assert_eq!(rings[1].len(), 4);
    }

    #[test]
    fn broken_polygons_say_what_is_wrong() {
        assert!(parse_wkt_polygon("LINESTRING (0 0, 1 1)", 100).is_err());
        assert!(parse_wkt_polygon("POLYGON ((0 0, 1 x, 1 1))", 100).is_err());
        assert!(parse_wkt_polygon("POLYGON ((0 0, 1 1))", 100).is_err());
        assert!(parse_wkt_polygon("POLYGON (", 100).is_err());
        assert!(parse_wkt_polygon("POLYGON ((0 0, inf 1, 1 1))", 100).is_err());
        assert!(parse_wkt_polygon("POLYGON EMPTY", 100).is_err());
        // Four points with a cap of three.
        assert!(parse_wkt_polygon("POLYGON ((0 0, 1 0, 1 1, 0 0))", 3).is_err());
        assert!(parse_wkt_polygon("POLYGON ((0 0, 1 0, 1 1, 0 0))", 4).is_ok());
    }
}

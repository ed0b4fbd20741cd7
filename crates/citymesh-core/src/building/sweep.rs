//! Finding a pair of overlapping boxes that passes a test, with a sweep along x: boxes are sorted
//! by their west edge and each is compared only with those that start before it ends. This keeps
//! ring validation near O(n log n) for real outlines instead of testing all n² edge pairs; its
//! worst case (every box overlapping every other in x) is bounded by the cap on ring vertices
//! ([`super::footprint::MAX_RING_VERTICES`]).

/// An axis-aligned box `[min_x, min_y, max_x, max_y]`.
pub type Bounds = [f64; 4];

/// Whether some pair `(i, j)`, `i < j`, of `boxes` overlaps (borders included) and passes
/// `test(i, j)`.
pub fn any_overlapping_pair(boxes: &[Bounds], mut test: impl FnMut(usize, usize) -> bool) -> bool {
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_unstable_by(|&p, &q| boxes[p][0].total_cmp(&boxes[q][0]));
    for (k, &p) in order.iter().enumerate() {
        let a = boxes[p];
        for &q in &order[k + 1..] {
            let b = boxes[q];
            if b[0] > a[2] {
                break;
            }
            if b[1] > a[3] || a[1] > b[3] {
                continue;
            }
            if test(p.min(q), p.max(q)) {
                return true;
            }
        }
    }
    false
}

/// The bounds of the segment `a`-`b`.
pub fn segment_bounds(a: [f64; 2], b: [f64; 2]) -> Bounds {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[0].max(b[0]),
        a[1].max(b[1]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute(boxes: &[Bounds], test: impl Fn(usize, usize) -> bool) -> bool {
        (0..boxes.len()).any(|i| {
            (i + 1..boxes.len()).any(|j| {
                let (a, b) = (boxes[i], boxes[j]);
                a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3] && test(i, j)
            })
        })
    }

    proptest! {
        /// The sweep finds exactly the pairs the all-pairs loop finds.
        #[test]
        fn agrees_with_all_pairs(
            raw in prop::collection::vec((0.0..100.0f64, 0.0..100.0f64, 0.0..20.0f64, 0.0..20.0f64), 0..60),
            modulus in 1usize..7,
        ) {
            let boxes: Vec<Bounds> = raw.iter().map(|&(x, y, w, h)| [x, y, x + w, y + h]).collect();
            // A test that accepts some overlapping pairs only.
            let test = |i: usize, j: usize| (i * 31 + j).is_multiple_of(modulus);
            prop_assert_eq!(any_overlapping_pair(&boxes, test), brute(&boxes, test));
        }
    }
}

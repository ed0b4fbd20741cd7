//! Stage 2 of the encoder: positions as the file stores them. Plain files keep f32 metres;
//! quantized ones (`KHR_mesh_quantization`) store whole steps in a box over the content, as u16,
//! and the node's matrix turns steps back into metres.

use super::encoding::Encoding;

/// The largest stored step count along an axis.
const STEPS: f64 = u16::MAX as f64;

/// Quantized positions are `offset + step * q`, with the same step along every axis (so normals
/// need no correction for a stretched box).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantization {
    pub offset: [f64; 3],
    pub step: f64,
}

/// One position per mesh vertex as stored: f32 metres, or whole step counts (exact in f32).
#[derive(Debug, Clone, PartialEq)]
pub struct Stored {
    pub positions: Vec<[f32; 3]>,
    pub quantization: Option<Quantization>,
}

/// Stores `placed` positions (file axes, metres) for `encoding`.
pub fn store<I>(placed: I, encoding: Encoding) -> Stored
where
    I: ExactSizeIterator<Item = [f64; 3]> + Clone,
{
    if !encoding.is_quantized() {
        return Stored {
            positions: placed.map(|p| p.map(|c| c as f32)).collect(),
            quantization: None,
        };
    }
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    let empty = placed.len() == 0;
    for p in placed.clone() {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    if empty {
        min = [0.0; 3];
        max = [0.0; 3];
    }
    let extent = (0..3).map(|k| max[k] - min[k]).fold(0.0, f64::max);
    let step = if extent > 0.0 { extent / STEPS } else { 1.0 };
    let positions = placed
        .map(|p| {
            let q = |k: usize| ((p[k] - min[k]) / step).round().clamp(0.0, STEPS) as f32;
            [q(0), q(1), q(2)]
        })
        .collect();
    Stored {
        positions,
        quantization: Some(Quantization { offset: min, step }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_longest_side_spans_all_steps() {
        let placed = [[10.0, 0.0, -5.0], [110.0, 20.0, -5.0], [60.0, 10.0, 45.0]];
        let stored = store(placed.iter().copied(), Encoding::Quantized);
        let q = stored.quantization.unwrap();
        assert_eq!(q.offset, [10.0, 0.0, -5.0]);
        assert_eq!(q.step, 100.0 / 65_535.0);
        assert_eq!(stored.positions[0], [0.0, 0.0, 0.0]);
        assert_eq!(stored.positions[1], [65_535.0, 13_107.0, 0.0]);
        // Back in metres within half a step.
        for (p, s) in placed.iter().zip(&stored.positions) {
            for k in 0..3 {
                let back = q.offset[k] + q.step * f64::from(s[k]);
                assert!((back - p[k]).abs() <= q.step / 2.0 + 1e-12);
            }
        }
    }

    #[test]
    fn plain_keeps_f32_metres() {
        let stored = store([[1.5, -2.25, 3.0]].into_iter(), Encoding::Plain);
        assert_eq!(stored.positions, [[1.5, -2.25, 3.0]]);
        assert_eq!(stored.quantization, None);
    }
}

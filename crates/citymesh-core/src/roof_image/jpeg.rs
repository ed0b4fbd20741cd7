//! JPEG-like compression artefacts, as imagery tiles carry them: 4:2:0 chroma subsampling and
//! 8x8 block DCT quantisation with the JPEG standard's tables (Annex K) scaled by a quality.
//! No file is written; the image is compressed and decompressed in place.

use super::image::{Image, linear_to_srgb8, srgb8_to_linear};

const LUMA: [u16; 64] = [
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
    14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113,
    92, 49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99,
];
const CHROMA: [u16; 64] = [
    17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99, 24, 26, 56, 99, 99, 99, 99, 99,
    47, 66, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
    99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
];

/// The quantisation table for a quality in 1..=100 (the IJG scaling).
fn scaled(table: &[u16; 64], quality: u8) -> [f32; 64] {
    let q = u32::from(quality.clamp(1, 100));
    let scale = if q < 50 { 5000 / q } else { 200 - 2 * q };
    table.map(|t| ((u32::from(t) * scale + 50) / 100).clamp(1, 255) as f32)
}

/// Compresses and decompresses `image` as a baseline JPEG of `quality` (1..=100) would.
pub fn jpeg_artefacts(image: &mut Image, quality: u8) {
    let (w, h) = (image.width, image.height);
    if w == 0 || h == 0 {
        return;
    }
    let mut planes = [
        vec![0.0f32; w * h],
        vec![0.0f32; w * h],
        vec![0.0f32; w * h],
    ];
    for (i, p) in image.pixels.iter().enumerate() {
        let [r, g, b] = p.map(|c| f32::from(linear_to_srgb8(c)));
        planes[0][i] = 0.299 * r + 0.587 * g + 0.114 * b - 128.0;
        planes[1][i] = -0.168_736 * r - 0.331_264 * g + 0.5 * b;
        planes[2][i] = 0.5 * r - 0.418_688 * g - 0.081_312 * b;
    }
    // 4:2:0: each 2x2 block of chroma shares its mean.
    for plane in &mut planes[1..] {
        for y in (0..h).step_by(2) {
            for x in (0..w).step_by(2) {
                let cells: Vec<usize> = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .filter(|(dx, dy)| x + dx < w && y + dy < h)
                    .map(|(dx, dy)| (y + dy) * w + x + dx)
                    .collect();
                let mean = cells.iter().map(|&i| plane[i]).sum::<f32>() / cells.len() as f32;
                for i in cells {
                    plane[i] = mean;
                }
            }
        }
    }
    let tables = [scaled(&LUMA, quality), scaled(&CHROMA, quality)];
    let basis = dct_basis();
    for (k, plane) in planes.iter_mut().enumerate() {
        let table = &tables[usize::from(k > 0)];
        for by in (0..h).step_by(8) {
            for bx in (0..w).step_by(8) {
                quantise_block(plane, w, h, bx, by, table, &basis);
            }
        }
    }
    for (i, p) in image.pixels.iter_mut().enumerate() {
        let (y, cb, cr) = (planes[0][i] + 128.0, planes[1][i], planes[2][i]);
        let rgb = [
            y + 1.402 * cr,
            y - 0.344_136 * cb - 0.714_136 * cr,
            y + 1.772 * cb,
        ];
        *p = rgb.map(|c| srgb8_to_linear(c.round().clamp(0.0, 255.0) as u8));
    }
}

/// `basis[u][x] = c(u) cos((2x + 1) u pi / 16)`, the orthonormal 8-point DCT-II.
fn dct_basis() -> [[f32; 8]; 8] {
    std::array::from_fn(|u| {
        std::array::from_fn(|x| {
            let c = if u == 0 { (1.0f32 / 8.0).sqrt() } else { 0.5 };
            c * ((2 * x + 1) as f32 * u as f32 * std::f32::consts::PI / 16.0).cos()
        })
    })
}

/// DCT, quantise, and inverse DCT of one 8x8 block (edge blocks repeat their last pixels).
fn quantise_block(
    plane: &mut [f32],
    w: usize,
    h: usize,
    bx: usize,
    by: usize,
    table: &[f32; 64],
    basis: &[[f32; 8]; 8],
) {
    let at = |x: usize, y: usize| (by + y).min(h - 1) * w + (bx + x).min(w - 1);
    let block: [[f32; 8]; 8] = std::array::from_fn(|y| std::array::from_fn(|x| plane[at(x, y)]));
    let mut coef = [[0.0f32; 8]; 8];
    for (v, row) in coef.iter_mut().enumerate() {
        for (u, c) in row.iter_mut().enumerate() {
            let mut s = 0.0;
            for (y, brow) in block.iter().enumerate() {
                for (x, &b) in brow.iter().enumerate() {
                    s += basis[u][x] * basis[v][y] * b;
                }
            }
            let q = table[v * 8 + u];
            *c = (s / q).round() * q;
        }
    }
    for y in 0..8.min(h - by) {
        for x in 0..8.min(w - bx) {
            let mut s = 0.0;
            for (v, row) in coef.iter().enumerate() {
                for (u, &c) in row.iter().enumerate() {
                    s += basis[u][x] * basis[v][y] * c;
                }
            }
            plane[at(x, y)] = s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flat_block_survives_and_detail_is_lost_at_low_quality() {
        let mut flat = Image::filled(16, 16, [srgb8_to_linear(120); 3]);
        jpeg_artefacts(&mut flat, 50);
        assert!(flat.to_srgb8().iter().all(|p| *p == [120, 120, 120]));

        // A faint one-pixel checkerboard (120/136) is high frequency: quality 30 removes it, 95
        // keeps it.
        let mut check = Image::filled(16, 16, [srgb8_to_linear(120); 3]);
        for y in 0..16 {
            for x in 0..16 {
                if (x + y) % 2 == 0 {
                    check.pixels[y * 16 + x] = [srgb8_to_linear(136); 3];
                }
            }
        }
        assert_eq!(contrast(&check), 8.0);
        let mut fine = check.clone();
        jpeg_artefacts(&mut fine, 95);
        assert!(contrast(&fine) > 6.0, "{}", contrast(&fine));
        jpeg_artefacts(&mut check, 30);
        assert!(contrast(&check) < 1.0, "{}", contrast(&check));
    }

    fn contrast(img: &Image) -> f32 {
        let v: Vec<f32> = img.to_srgb8().iter().map(|p| f32::from(p[0])).collect();
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        v.iter().map(|x| (x - mean).abs()).sum::<f32>() / v.len() as f32
    }
}

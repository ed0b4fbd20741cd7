//! Developing a rendered scene like imagery: colour balance, haze, blur and noise.

use crate::roof_image::image::Image;
use crate::roof_image::jpeg::jpeg_artefacts;
use crate::roof_image::noise;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Camera and sensor effects on rendered imagery: colour balance, haze, blur, noise, JPEG.
pub(super) fn develop(img: &mut Image, rng: &mut ChaCha8Rng) {
    let exposure = rng.random_range(0.75..1.3f32);
    let gains: [f32; 3] = std::array::from_fn(|_| rng.random_range(0.9..1.1f32));
    let haze = rng.random_range(0.0..0.1f32);
    let haze_colour = [0.55, 0.6, 0.7];
    for p in &mut img.pixels {
        for k in 0..3 {
            p[k] = (p[k] * exposure * gains[k]) * (1.0 - haze) + haze_colour[k] * haze;
        }
    }
    let sigma = rng.random_range(0.0..1.0f32);
    if sigma > 0.25 {
        gaussian_blur(img, sigma);
    }
    let grain = rng.random_range(0.0..0.025f32);
    let seed = rng.random::<u64>();
    for (i, p) in img.pixels.iter_mut().enumerate() {
        let n = (noise::hash01(i as i64, 0, seed) - 0.5) * 2.0 * grain;
        let bright = p.iter().sum::<f32>() / 3.0;
        // Noise in roughly perceptual units: larger in bright areas of linear light.
        let scale = 2.0 * bright.max(0.02).sqrt();
        for c in p.iter_mut() {
            *c = (*c + n * scale).max(0.0);
        }
    }
    if rng.random_bool(0.85) {
        jpeg_artefacts(img, rng.random_range(30..95u8));
    }
}

/// A separable Gaussian blur.
pub(super) fn gaussian_blur(img: &mut Image, sigma: f32) {
    let r = (sigma * 2.5).ceil() as i64;
    let kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f32 = kernel.iter().sum();
    let (w, h) = (img.width as i64, img.height as i64);
    for horizontal in [true, false] {
        let src = img.pixels.clone();
        for y in 0..h {
            for x in 0..w {
                let mut acc = [0.0f32; 3];
                for (k, &kv) in kernel.iter().enumerate() {
                    let d = k as i64 - r;
                    let (sx, sy) = if horizontal {
                        ((x + d).clamp(0, w - 1), y)
                    } else {
                        (x, (y + d).clamp(0, h - 1))
                    };
                    let s = src[(sy * w + sx) as usize];
                    for c in 0..3 {
                        acc[c] += s[c] * kv;
                    }
                }
                img.pixels[(y * w + x) as usize] = acc.map(|a| a / total);
            }
        }
    }
}

//! An RGB image in linear light, row 0 at the top (north).

/// An RGB image with `f32` channels in linear light (0 black, 1 white).
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    /// An image filled with one colour.
    pub fn filled(width: usize, height: usize, colour: [f32; 3]) -> Self {
        Self {
            width,
            height,
            pixels: vec![colour; width * height],
        }
    }

    /// The pixel at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        self.pixels[y * self.width + x]
    }

    /// The colour at continuous pixel coordinates (pixel centres at `i + 0.5`), bilinear, clamped
    /// at the edges.
    pub fn bilinear(&self, x: f64, y: f64) -> [f32; 3] {
        if self.width == 0 || self.height == 0 {
            return [0.0; 3];
        }
        let fx = (x - 0.5).clamp(0.0, (self.width - 1) as f64);
        let fy = (y - 0.5).clamp(0.0, (self.height - 1) as f64);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (tx, ty) = ((fx - x0 as f64) as f32, (fy - y0 as f64) as f32);
        let (a, b, c, d) = (
            self.get(x0, y0),
            self.get(x1, y0),
            self.get(x0, y1),
            self.get(x1, y1),
        );
        std::array::from_fn(|k| {
            let top = a[k] + (b[k] - a[k]) * tx;
            let bottom = c[k] + (d[k] - c[k]) * tx;
            top + (bottom - top) * ty
        })
    }

    /// The image as 8-bit sRGB, row by row.
    pub fn to_srgb8(&self) -> Vec<[u8; 3]> {
        self.pixels.iter().map(|p| p.map(linear_to_srgb8)).collect()
    }

    /// An image from 8-bit sRGB pixels, row by row; `None` when the count does not match.
    pub fn from_srgb8(width: usize, height: usize, pixels: &[[u8; 3]]) -> Option<Self> {
        (pixels.len() == width * height).then(|| Self {
            width,
            height,
            pixels: pixels.iter().map(|p| p.map(srgb8_to_linear)).collect(),
        })
    }
}

/// Linear light to an 8-bit sRGB value.
pub fn linear_to_srgb8(l: f32) -> u8 {
    let l = l.clamp(0.0, 1.0);
    let s = if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// An 8-bit sRGB value in linear light.
pub fn srgb8_to_linear(v: u8) -> f32 {
    SRGB8_TO_LINEAR[usize::from(v)]
}

static SRGB8_TO_LINEAR: std::sync::LazyLock<[f32; 256]> = std::sync::LazyLock::new(|| {
    std::array::from_fn(|c| {
        let s = c as f32 / 255.0;
        if s <= 0.04045 {
            s / 12.92
        } else {
            ((s + 0.055) / 1.055).powf(2.4)
        }
    })
});

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_byte() {
        for v in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(v)), v);
        }
    }

    #[test]
    fn bilinear_interpolates_between_pixel_centres() {
        let mut img = Image::filled(2, 1, [0.0; 3]);
        img.pixels[1] = [1.0; 3];
        assert_eq!(img.bilinear(0.5, 0.5), [0.0; 3]);
        assert_eq!(img.bilinear(1.0, 0.5), [0.5; 3]);
        assert_eq!(img.bilinear(1.5, 0.5), [1.0; 3]);
        // Clamped outside.
        assert_eq!(img.bilinear(-3.0, 9.0), [0.0; 3]);
    }
}

//! sRGB colours.

/// An 8-bit sRGB colour, as OSM tags and CSS write them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    /// The default ground colour: a muted green-grey.
    pub const GROUND: Rgb = Rgb(0x9a, 0xa8, 0x86);

    /// `#rrggbb`, as CSS writes it.
    pub fn hex(self) -> String {
        format!("#{:02x}{:02x}{:02x}", self.0, self.1, self.2)
    }

    /// The colour in linear light, as glTF vertex colours are defined, each channel in 0..=255.
    #[inline]
    pub fn to_linear_u8(self) -> [u8; 3] {
        let lut = &*SRGB_TO_LINEAR;
        [
            lut[usize::from(self.0)],
            lut[usize::from(self.1)],
            lut[usize::from(self.2)],
        ]
    }
}

/// The sRGB transfer curve inverted, per 8-bit value.
static SRGB_TO_LINEAR: std::sync::LazyLock<[u8; 256]> = std::sync::LazyLock::new(|| {
    std::array::from_fn(|c| {
        let s = c as f64 / 255.0;
        let l = if s <= 0.04045 {
            s / 12.92
        } else {
            ((s + 0.055) / 1.055).powf(2.4)
        };
        (l * 255.0).round() as u8
    })
});

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linearises_by_the_srgb_curve() {
        assert_eq!(Rgb(0, 128, 255).to_linear_u8(), [0, 55, 255]);
    }
}

//! Any image of one building to the model's crop, by the crop rule.
//!
//! With a footprint mask (the image's alpha channel, opaque inside), the mask's minimum rotated
//! rectangle is the footprint's and the crop rule applies exactly: turned long side horizontal,
//! scaled to the rule's fill share, the mask sampled along as the fourth channel. Without one,
//! the image is taken as already centred on its building: it is turned by its dominant edge
//! direction (so the building's sides are axis-aligned) and the largest centred square that fits
//! is resampled to the crop's size, with the mask marked unknown.

use super::ClassifierError;
use citymesh_core::roof_image::crop::{dominant_direction, min_rotated_rect};
use citymesh_core::roof_image::png_metadata::{MAX_PNG_TEXT_BYTES, png_text_bytes};
use citymesh_core::roof_image::{Crop, CropFrame, CropRule, Image};

/// Largest image side accepted (pixels), and the most bytes the decoder may allocate.
pub const MAX_SIDE: u32 = 8192;
const MAX_ALLOC: u64 = 512 << 20;

/// A decoded image: its colours and, when it has an alpha channel, the alpha values.
struct Decoded {
    image: Image,
    alpha: Option<Vec<u8>>,
}

/// Decodes PNG or JPEG bytes within the side and allocation limits.
fn decode(bytes: &[u8]) -> Result<Decoded, ClassifierError> {
    let text = png_text_bytes(bytes);
    if text > MAX_PNG_TEXT_BYTES {
        return Err(ClassifierError::Input(format!(
            "the PNG carries {text} bytes of text metadata, more than {MAX_PNG_TEXT_BYTES}: \
             strip its metadata"
        )));
    }
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| ClassifierError::Input(e.to_string()))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(MAX_ALLOC);
    reader.limits(limits);
    let decoded = reader
        .decode()
        .map_err(|e| ClassifierError::Input(format!("not a readable PNG or JPEG image: {e}")))?;
    let has_alpha = decoded.color().has_alpha();
    let rgba = decoded.into_rgba8();
    let (w, h) = (rgba.width() as usize, rgba.height() as usize);
    if w < 2 || h < 2 {
        return Err(ClassifierError::Input(format!(
            "the image is {w}x{h} px; at least 2x2 is needed"
        )));
    }
    let rgb: Vec<[u8; 3]> = rgba.pixels().map(|p| [p[0], p[1], p[2]]).collect();
    let image = Image::from_srgb8(w, h, &rgb)
        .ok_or_else(|| ClassifierError::Input("pixel count mismatch".into()))?;
    let alpha = has_alpha.then(|| rgba.pixels().map(|p| p[3]).collect());
    Ok(Decoded { image, alpha })
}

/// World coordinates of a pixel position: pixels, y up, so a crop's frame reads them as metres.
fn to_world(p: [f64; 2]) -> [f64; 2] {
    [p[0], -p[1]]
}

/// Decodes PNG or JPEG bytes and crops them by `rule` around a footprint given in the image's
/// pixel coordinates (x right, y down; outer ring first, then holes), exactly as citymesh crops
/// imagery around an OSM footprint: the footprint's rotated rectangle frames the crop and the
/// footprint is the mask.
pub fn crop_footprint_image(
    bytes: &[u8],
    rings_px: &[Vec<[f64; 2]>],
    rule: CropRule,
) -> Result<Crop, ClassifierError> {
    let decoded = decode(bytes)?;
    let rings: Vec<Vec<[f64; 2]>> = rings_px
        .iter()
        .map(|r| r.iter().copied().map(to_world).collect())
        .collect();
    let outer = rings
        .first()
        .ok_or_else(|| ClassifierError::Input("the footprint has no ring".into()))?;
    let frame = CropFrame::of_footprint(outer, rule)
        .ok_or_else(|| ClassifierError::Input("the footprint has no extent".into()))?;
    Ok(Crop {
        size: rule.size,
        rgb: frame.sample(&decoded.image, to_world, 1.0),
        mask: Some(frame.mask(&rings)),
    })
}

/// Decodes PNG or JPEG bytes and crops them by `rule`; `use_mask` takes the footprint from the
/// alpha channel.
pub fn crop_image(bytes: &[u8], use_mask: bool, rule: CropRule) -> Result<Crop, ClassifierError> {
    let Decoded { image, alpha } = decode(bytes)?;
    let (w, h) = (image.width, image.height);
    let to_pixel = to_world;
    if use_mask {
        let Some(alpha) = alpha else {
            return Err(ClassifierError::Input(
                "--footprint-mask needs an alpha channel (opaque inside the footprint); this image has none".into(),
            ));
        };
        let mut corners = Vec::new();
        for y in 0..h {
            for x in 0..w {
                if alpha[y * w + x] >= 128 {
                    let (x, y) = (x as f64, y as f64);
                    corners.extend([[x, -y], [x + 1.0, -y], [x, -y - 1.0], [x + 1.0, -y - 1.0]]);
                }
            }
        }
        let rect = min_rotated_rect(&corners).ok_or_else(|| {
            ClassifierError::Input("the footprint mask (alpha >= 128) is empty".into())
        })?;
        let frame = CropFrame {
            centre: rect.centre,
            axis: rect.axis,
            metres_per_pixel: rect.length / (rule.fill * rule.size as f64),
            size: rule.size,
        };
        let mask_image = Image {
            width: w,
            height: h,
            pixels: alpha.iter().map(|&a| [f32::from(a) / 255.0; 3]).collect(),
        };
        let mask = sample_linear(&frame, &mask_image, to_pixel)
            .into_iter()
            .map(|v| if v >= 0.5 { 255 } else { 0 })
            .collect();
        Ok(Crop {
            size: rule.size,
            rgb: frame.sample(&image, to_pixel, 1.0),
            mask: Some(mask),
        })
    } else {
        let turn = dominant_direction(&image).unwrap_or(0.0);
        let side = w.min(h) as f64 / (turn.cos().abs() + turn.sin().abs());
        let frame = CropFrame {
            centre: [w as f64 / 2.0, -(h as f64) / 2.0],
            axis: [turn.cos(), turn.sin()],
            metres_per_pixel: side / rule.size as f64,
            size: rule.size,
        };
        Ok(Crop {
            size: rule.size,
            rgb: frame.sample(&image, to_pixel, 1.0),
            mask: None,
        })
    }
}

/// The first channel of `image` sampled into the crop without any transfer curve.
fn sample_linear(
    frame: &CropFrame,
    image: &Image,
    to_pixel: impl Fn([f64; 2]) -> [f64; 2],
) -> Vec<f32> {
    let mut out = Vec::with_capacity(frame.size * frame.size);
    for y in 0..frame.size {
        for x in 0..frame.size {
            let p = to_pixel(frame.world_at(x as f64 + 0.5, y as f64 + 0.5));
            out.push(image.bilinear(p[0], p[1])[0]);
        }
    }
    out
}

//! `citymesh render-roofs`: writes a seeded training or test set of roof crops rendered by the
//! core's synthetic scenes, as PNG files (RGBA with the footprint mask in alpha when the sample
//! has one, RGB when not) and a `labels.csv`.

use super::ClassifierError;
use super::labelled::LabelledImage;
use crate::source::read_osm_file;
use citymesh_core::osm::read_buildings;
use citymesh_core::roof_image::synthetic::{FootprintPool, Palette, render_sample};
use citymesh_core::roof_image::{Crop, CropRule};
use std::io::Write;
use std::path::{Path, PathBuf};

/// What to render.
#[derive(Debug, Clone)]
pub struct TrainingSetSpec {
    /// OSM files whose real footprints are drawn (each one pool).
    pub osm: Vec<PathBuf>,
    /// Procedural cities (one pool per seed) drawn as well.
    pub procedural_seeds: Vec<u64>,
    pub count: u64,
    pub seed: u64,
    pub palette: Palette,
    pub out: PathBuf,
}

/// How many samples were written, per class.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TrainingSetReport {
    pub written: u64,
    pub per_class: [u64; 3],
    pub failed: u64,
}

/// Renders the set on every core and writes it. Blocking.
pub fn render_training_set(spec: &TrainingSetSpec) -> Result<TrainingSetReport, ClassifierError> {
    let mut pools: Vec<(String, FootprintPool)> = Vec::new();
    for path in &spec.osm {
        let bytes = read_osm_file(path).map_err(|e| ClassifierError::Input(e.to_string()))?;
        let buildings = read_buildings(&bytes)
            .map_err(|e| ClassifierError::Input(format!("{}: {e}", path.display())))?;
        let name = path
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        pools.push((name, FootprintPool::from_records(&buildings.buildings)));
    }
    for &s in &spec.procedural_seeds {
        pools.push((format!("procedural-{s}"), FootprintPool::procedural(s)));
    }
    pools.retain(|(_, p)| !p.targets().is_empty());
    if pools.is_empty() {
        return Err(ClassifierError::Input(
            "no footprints to draw from: give --osm files or --procedural seeds".into(),
        ));
    }
    let images = spec.out.join("images");
    std::fs::create_dir_all(&images).map_err(|e| io_error(&images, e))?;
    let threads = std::thread::available_parallelism().map_or(1, usize::from) as u64;
    let rule = CropRule::MODEL;
    let rows: Vec<Vec<(u64, String)>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let pools = &pools;
                let images = &images;
                scope.spawn(move || {
                    let mut rows = Vec::new();
                    for i in (t..spec.count).step_by(threads as usize) {
                        let seed = spec.seed.wrapping_mul(1_000_003).wrapping_add(i);
                        let (pool_name, pool) = &pools[(i / 3) as usize % pools.len()];
                        let Some(sample) = render_sample(pool, seed, spec.palette, rule) else {
                            rows.push((i, String::new()));
                            continue;
                        };
                        let file = format!("{i:06}.png");
                        if write_png(&images.join(&file), &sample.crop).is_err() {
                            rows.push((i, String::new()));
                            continue;
                        }
                        rows.push((
                            i,
                            format!(
                                "images/{file},{},{},{},{:.3},{pool_name}",
                                sample.class.name(),
                                sample.shape.tag(),
                                u8::from(sample.crop.mask.is_some()),
                                sample.imagery_metres_per_pixel
                            ),
                        ));
                    }
                    rows
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_default())
            .collect()
    });
    let mut all: Vec<(u64, String)> = rows.into_iter().flatten().collect();
    all.sort_by_key(|(i, _)| *i);
    let labels = spec.out.join("labels.csv");
    let mut csv =
        std::io::BufWriter::new(std::fs::File::create(&labels).map_err(|e| io_error(&labels, e))?);
    let mut report = TrainingSetReport::default();
    writeln!(csv, "file,class,shape,mask,imagery_m_per_px,footprints")
        .map_err(|e| io_error(&labels, e))?;
    for (_, row) in all {
        if row.is_empty() {
            report.failed += 1;
            continue;
        }
        let class = row.split(',').nth(1).unwrap_or_default();
        if let Some(c) = citymesh_core::roof_image::RoofClass::from_name(class) {
            report.per_class[c.index()] += 1;
        }
        report.written += 1;
        writeln!(csv, "{row}").map_err(|e| io_error(&labels, e))?;
    }
    csv.flush().map_err(|e| io_error(&labels, e))?;
    Ok(report)
}

/// Crops labelled real images (of `split` only, when given) by the model's crop rule and writes
/// them as [`render_training_set`] writes renders, with the source file and split as extra
/// columns. A row whose image cannot be cropped is counted as failed and named on stderr.
pub fn write_labelled_set(
    rows: &[LabelledImage],
    split: Option<&str>,
    out: &Path,
) -> Result<TrainingSetReport, ClassifierError> {
    let images = out.join("images");
    std::fs::create_dir_all(&images).map_err(|e| io_error(&images, e))?;
    let labels = out.join("labels.csv");
    let mut csv =
        std::io::BufWriter::new(std::fs::File::create(&labels).map_err(|e| io_error(&labels, e))?);
    writeln!(
        csv,
        "file,class,shape,mask,imagery_m_per_px,footprints,source,split"
    )
    .map_err(|e| io_error(&labels, e))?;
    let mut report = TrainingSetReport::default();
    let chosen = rows
        .iter()
        .filter(|r| split.is_none() || r.split.as_deref() == split);
    for (i, row) in chosen.enumerate() {
        let crop = match row.crop(CropRule::MODEL) {
            Ok(crop) => crop,
            Err(e) => {
                eprintln!("skipped: {e}");
                report.failed += 1;
                continue;
            }
        };
        let file = format!("{i:06}.png");
        write_png(&images.join(&file), &crop)?;
        writeln!(
            csv,
            "images/{file},{},{},{},,labelled,{},{}",
            row.label.name(),
            row.label.name(),
            u8::from(crop.mask.is_some()),
            row.name.replace(',', "_"),
            row.split.as_deref().unwrap_or("").replace(',', "_"),
        )
        .map_err(|e| io_error(&labels, e))?;
        report.per_class[row.label.index()] += 1;
        report.written += 1;
    }
    csv.flush().map_err(|e| io_error(&labels, e))?;
    Ok(report)
}

/// Writes a crop as PNG: RGBA with the mask as alpha when it has one, else RGB.
pub fn write_png(path: &Path, crop: &Crop) -> Result<(), ClassifierError> {
    let size = crop.size as u32;
    let result = match &crop.mask {
        Some(mask) => {
            let data: Vec<u8> = crop
                .rgb
                .iter()
                .zip(mask)
                .flat_map(|(p, &m)| [p[0], p[1], p[2], m])
                .collect();
            image::save_buffer(path, &data, size, size, image::ExtendedColorType::Rgba8)
        }
        None => {
            let data: Vec<u8> = crop.rgb.iter().flatten().copied().collect();
            image::save_buffer(path, &data, size, size, image::ExtendedColorType::Rgb8)
        }
    };
    result.map_err(|e| ClassifierError::Input(format!("{}: {e}", path.display())))
}

fn io_error(path: &Path, e: std::io::Error) -> ClassifierError {
    ClassifierError::Input(format!("{}: {e}", path.display()))
}

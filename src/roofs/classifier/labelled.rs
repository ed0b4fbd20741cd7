//! Labelled roof images: a CSV of `file,label` with optional `split` and `footprint_px_wkt`
//! columns (the layout of the Atlanta set), images relative to the CSV (or in its `images/`
//! folder). Each image is cropped
//! by citymesh's own crop rule: around its footprint (drawn as the mask) when the row has one,
//! as a centred image otherwise.

use super::ClassifierError;
use super::input::{crop_footprint_image, crop_image};
use citymesh_core::geo::parse_wkt_polygon;
use citymesh_core::roof_image::{Crop, CropRule, RoofClass};
use std::path::{Path, PathBuf};

/// Most rows read from one labels file.
pub const MAX_ROWS: usize = 200_000;
/// Largest image file read (bytes).
pub const MAX_FILE_BYTES: u64 = 64 << 20;
/// Most vertices of one footprint.
const MAX_FOOTPRINT_VERTICES: usize = 100_000;

/// One row of a labels file.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledImage {
    /// The image file (joined to the CSV's folder).
    pub file: PathBuf,
    /// The file as the CSV names it.
    pub name: String,
    pub label: RoofClass,
    /// The row's `split` (e.g. `train`, `val`), when the CSV has that column.
    pub split: Option<String>,
    /// The footprint in the image's pixels (x right, y down): outer ring, then holes.
    pub footprint: Option<Vec<Vec<[f64; 2]>>>,
}

impl LabelledImage {
    /// The model's crop of this image by `rule`.
    pub fn crop(&self, rule: CropRule) -> Result<Crop, ClassifierError> {
        let bytes = read_limited(&self.file)?;
        match &self.footprint {
            Some(rings) => crop_footprint_image(&bytes, rings, rule),
            None => crop_image(&bytes, false, rule),
        }
        .map_err(|e| ClassifierError::Input(format!("{}: {e}", self.name)))
    }
}

/// How a classifier did on labelled images.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LabelledReport {
    /// Images classified (those that could be cropped).
    pub count: usize,
    pub correct: usize,
    pub accuracy: f64,
    /// `confusion[truth][predicted]`, classes flat, gabled, hipped.
    pub confusion: [[usize; 3]; 3],
    /// Images that could not be cropped, with why.
    pub failed: Vec<String>,
    /// Each classified image's name, truth and prediction, in order.
    #[serde(skip)]
    pub predictions: Vec<(String, RoofClass, super::Prediction)>,
}

/// Crops every image by `rule` (footprint mask when the row has one) and classifies it.
pub fn evaluate(
    classifier: &dyn super::RoofClassifier,
    rows: &[LabelledImage],
    rule: CropRule,
) -> Result<LabelledReport, ClassifierError> {
    let mut report = LabelledReport {
        count: 0,
        correct: 0,
        accuracy: 0.0,
        confusion: [[0; 3]; 3],
        failed: Vec::new(),
        predictions: Vec::new(),
    };
    for chunk in rows.chunks(64) {
        let mut crops = Vec::with_capacity(chunk.len());
        let mut named = Vec::with_capacity(chunk.len());
        for row in chunk {
            match row.crop(rule) {
                Ok(c) => {
                    crops.push(c);
                    named.push(row);
                }
                Err(e) => report.failed.push(e.to_string()),
            }
        }
        for (row, p) in named.iter().zip(classifier.classify(&crops)?) {
            report.confusion[row.label.index()][p.class().index()] += 1;
            report.count += 1;
            report.correct += usize::from(p.class() == row.label);
            report.predictions.push((row.name.clone(), row.label, p));
        }
    }
    report.accuracy = report.correct as f64 / report.count.max(1) as f64;
    Ok(report)
}

/// Reads a labels file. Labels must be `flat`, `gabled` or `hipped`; a bad row is an error that
/// names its line.
pub fn read_labels(csv_path: &Path) -> Result<Vec<LabelledImage>, ClassifierError> {
    let bad = |msg: String| ClassifierError::Input(format!("{}: {msg}", csv_path.display()));
    let mut reader = csv::ReaderBuilder::new()
        .flexible(false)
        .from_path(csv_path)
        .map_err(|e| bad(e.to_string()))?;
    let headers = reader.headers().map_err(|e| bad(e.to_string()))?.clone();
    let column = |name: &str| headers.iter().position(|h| h.trim() == name);
    let (Some(file_col), Some(label_col)) = (column("file"), column("label")) else {
        return Err(bad(format!(
            "needs the columns `file` and `label` (it has: {})",
            headers.iter().collect::<Vec<_>>().join(", ")
        )));
    };
    let split_col = column("split");
    let wkt_col = column("footprint_px_wkt");
    let folder = csv_path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let line = i + 2;
        if out.len() >= MAX_ROWS {
            return Err(bad(format!("more than {MAX_ROWS} rows")));
        }
        let record = record.map_err(|e| bad(format!("line {line}: {e}")))?;
        let field = |c: usize| record.get(c).unwrap_or("").trim();
        let name = field(file_col).to_owned();
        if name.is_empty() {
            return Err(bad(format!("line {line}: the file is empty")));
        }
        let label = RoofClass::from_name(field(label_col)).ok_or_else(|| {
            bad(format!(
                "line {line}: label `{}` is not flat, gabled or hipped",
                field(label_col)
            ))
        })?;
        let footprint = match wkt_col.map(field) {
            Some(w) if !w.is_empty() => Some(
                parse_wkt_polygon(w, MAX_FOOTPRINT_VERTICES)
                    .map_err(|e| bad(format!("line {line}: footprint_px_wkt: {e}")))?,
            ),
            _ => None,
        };
        // Images lie beside the CSV or, as in the Atlanta set, in its `images/` folder.
        let beside = folder.join(&name);
        let file = if beside.exists() {
            beside
        } else {
            let inside = folder.join("images").join(&name);
            if inside.exists() { inside } else { beside }
        };
        out.push(LabelledImage {
            file,
            name,
            label,
            split: split_col.map(|c| field(c).to_owned()),
            footprint,
        });
    }
    Ok(out)
}

/// Reads a file of at most [`MAX_FILE_BYTES`].
pub fn read_limited(path: &Path) -> Result<Vec<u8>, ClassifierError> {
    use std::io::Read;
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_FILE_BYTES + 1).read_to_end(&mut bytes))
        .map_err(|e| ClassifierError::Input(format!("{}: {e}", path.display())))?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(ClassifierError::Input(format!(
            "{}: larger than {} MiB",
            path.display(),
            MAX_FILE_BYTES >> 20
        )));
    }
    Ok(bytes)
}

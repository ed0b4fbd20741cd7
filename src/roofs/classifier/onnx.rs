//! [`RoofClassifier`] with an ONNX model run by ONNX Runtime (`ort`, loaded dynamically).

use super::{ClassifierError, Prediction, RoofClassifier, model_id_of};
use citymesh_core::roof_image::Crop;
use ort::environment::Environment;
use ort::session::Session;
use ort::value::Tensor;
use std::path::Path;
use std::sync::{Mutex, OnceLock};

/// Crops per inference call at most (each run in up to 8 turns and flips at 5 shifts: 640 rows
/// of 96 x 96 x 4 floats, 94 MB, at most).
pub const MAX_BATCH: usize = 16;

/// The shifts (rows, columns; wrapping around as numpy's `roll`) each turn is also run at: none,
/// and 2 px each way. The crop rule centres the building only to a pixel or two and training
/// shifted crops by up to 3 px, so averaging over these steadies the answer.
const SHIFTS: [(isize, isize); 5] = [(0, 0), (2, 0), (-2, 0), (0, 2), (0, -2)];

/// The passes a crop is run in (test-time augmentation), a choice of accuracy against cost.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Passes {
    /// The turns and flips, each at 5 shifts: 20 passes for a crop with a footprint, 40
    /// without: five times the cost of `turns`.
    Shifted,
    /// The turns and flips only: 4 passes for a crop with a footprint, 8 without (the model
    /// card's figures).
    #[default]
    Turns,
}

impl Passes {
    /// The shifts each turn is run at.
    fn shifts(self) -> &'static [(isize, isize)] {
        match self {
            Self::Shifted => &SHIFTS,
            Self::Turns => &SHIFTS[..1],
        }
    }
}

/// The 8 turns and flips of a square crop: every element of the dihedral group. A crop without a
/// footprint is run in all of them and the answers averaged (how it happens to be turned then
/// says nothing).
const TURNS: [(bool, u8); 8] = [
    (false, 0),
    (false, 1),
    (false, 2),
    (false, 3),
    (true, 0),
    (true, 1),
    (true, 2),
    (true, 3),
];

/// The turns and flips of a rectangle: those that keep a crop's long side horizontal. A crop
/// cut by the crop rule from a known footprint is run in these only, as the model was trained
/// (`train.py --symmetry rect`).
const RECTANGLE_TURNS: [(bool, u8); 4] = [(false, 0), (false, 2), (true, 0), (true, 2)];

/// The turns and flips a crop is run in.
fn turns_of(crop: &Crop) -> &'static [(bool, u8)] {
    if crop.mask.is_some() {
        &RECTANGLE_TURNS
    } else {
        &TURNS
    }
}

/// `tensor` (C x n x n, planar) shifted by `shift` (rows, columns; wrapping around), then
/// flipped left-right when `flip`, then turned `k` quarter turns.
fn shifted_turned(
    tensor: &[f32],
    n: usize,
    shift: (isize, isize),
    flip: bool,
    k: u8,
    out: &mut Vec<f32>,
) {
    let plane = n * n;
    let wrap = |v: usize, by: isize| (v as isize - by).rem_euclid(n as isize) as usize;
    for c in 0..tensor.len() / plane {
        let src = &tensor[c * plane..(c + 1) * plane];
        for i in 0..n {
            for j in 0..n {
                let (a, b) = match k {
                    0 => (i, j),
                    1 => (j, n - 1 - i),
                    2 => (n - 1 - i, n - 1 - j),
                    _ => (n - 1 - j, i),
                };
                let b = if flip { n - 1 - b } else { b };
                out.push(src[wrap(a, shift.0) * n + wrap(b, shift.1)]);
            }
        }
    }
}

/// The model, loaded into an ONNX Runtime session.
pub struct OnnxClassifier {
    // The session needs the environment alive.
    _environment: Environment,
    session: Mutex<Session>,
    model_id: String,
    size: usize,
    passes: Passes,
}

/// The runtime library and its environment, once per process (ONNX Runtime allows one
/// environment): later loads must name the same file and share the environment.
static LOADED: OnceLock<Result<(std::path::PathBuf, Environment), String>> = OnceLock::new();

impl OnnxClassifier {
    /// Loads ONNX Runtime from `library` (once per process) and the model from its bytes, which
    /// take crops of `size` pixels, run in `passes`. One intra-op thread: callers parallelise
    /// across requests.
    pub fn load(
        library: &Path,
        model: &[u8],
        size: usize,
        passes: Passes,
    ) -> Result<Self, ClassifierError> {
        let loaded = LOADED.get_or_init(|| {
            let builder = ort::init_from(library)
                .map_err(|e| format!("could not load {}: {e}", library.display()))?;
            let environment = builder
                .with_name("citymesh")
                .build()
                .map_err(|e| format!("ONNX Runtime from {}: {e}", library.display()))?;
            Ok((library.to_path_buf(), environment))
        });
        let environment = match loaded {
            Ok((path, environment)) if path == library => environment.clone(),
            Ok((path, _)) => {
                return Err(ClassifierError::Runtime(format!(
                    "ONNX Runtime is already loaded from {}",
                    path.display()
                )));
            }
            Err(e) => return Err(ClassifierError::Runtime(e.clone())),
        };
        let session = Session::builder(&environment)
            .map_err(|e| ClassifierError::Runtime(e.to_string()))?
            .with_intra_threads(1)
            .map_err(|e| ClassifierError::Runtime(e.to_string()))?
            .commit_from_memory(model)
            .map_err(|e| ClassifierError::Model(e.to_string()))?;
        Ok(Self {
            _environment: environment,
            session: Mutex::new(session),
            model_id: model_id_of(model),
            size,
            passes,
        })
    }

    /// The runs of one crop: each of its turns at each shift.
    fn runs_of(&self, crop: &Crop) -> usize {
        turns_of(crop).len() * self.passes.shifts().len()
    }
}

impl RoofClassifier for OnnxClassifier {
    fn model_id(&self) -> &str {
        &self.model_id
    }

    fn crop_size(&self) -> usize {
        self.size
    }

    fn classify(&self, crops: &[Crop]) -> Result<Vec<Prediction>, ClassifierError> {
        Ok(self
            .run(crops, false)?
            .into_iter()
            .map(|e| e.prediction)
            .collect())
    }
}

/// The model's answer for one crop with what its head saw: the embedding of each pass.
#[derive(Debug, Clone, PartialEq)]
pub struct Embedded {
    /// The shipped head's probabilities, averaged over the passes.
    pub prediction: Prediction,
    /// One embedding per pass (turn, flip and shift), in run order.
    pub embeddings: Vec<Vec<f32>>,
}

impl OnnxClassifier {
    /// Like [`RoofClassifier::classify`], with the embedding of every pass (the model's
    /// `embedding` output, which a model without one cannot give).
    pub fn classify_embedded(&self, crops: &[Crop]) -> Result<Vec<Embedded>, ClassifierError> {
        self.run(crops, true)
    }

    fn run(&self, crops: &[Crop], embed: bool) -> Result<Vec<Embedded>, ClassifierError> {
        let mut out = Vec::with_capacity(crops.len());
        for batch in crops.chunks(MAX_BATCH) {
            let n = self.size * self.size;
            let rows: usize = batch.iter().map(|c| self.runs_of(c)).sum();
            let mut input = Vec::with_capacity(rows * 4 * n);
            for crop in batch {
                if crop.size != self.size {
                    return Err(ClassifierError::Input(format!(
                        "crop of {} px; the model takes {} px",
                        crop.size, self.size
                    )));
                }
                let tensor = crop.tensor();
                for &shift in self.passes.shifts() {
                    for &(flip, k) in turns_of(crop) {
                        shifted_turned(&tensor, self.size, shift, flip, k, &mut input);
                    }
                }
            }
            let shape = [rows, 4, self.size, self.size];
            let tensor = Tensor::from_array((shape, input))
                .map_err(|e| ClassifierError::Runtime(e.to_string()))?;
            let mut session = self
                .session
                .lock()
                .map_err(|_| ClassifierError::Runtime("the session lock was poisoned".into()))?;
            let outputs = session
                .run(ort::inputs!["crops" => tensor])
                .map_err(|e| ClassifierError::Model(e.to_string()))?;
            let (shape, probs) = outputs["probabilities"]
                .try_extract_tensor::<f32>()
                .map_err(|e| ClassifierError::Model(e.to_string()))?;
            if shape.len() != 2 || shape[1] != 3 || probs.len() != 3 * rows {
                return Err(ClassifierError::Model(format!(
                    "unexpected output shape {shape:?}"
                )));
            }
            let embeddings: Option<(usize, &[f32])> = if embed {
                let value = outputs.get("embedding").ok_or_else(|| {
                    ClassifierError::Model(
                        "the model has no `embedding` output, so no head can be fitted on it"
                            .into(),
                    )
                })?;
                let (shape, values) = value
                    .try_extract_tensor::<f32>()
                    .map_err(|e| ClassifierError::Model(e.to_string()))?;
                let dims = shape.get(1).copied().unwrap_or(0).max(0) as usize;
                if shape.len() != 2 || dims == 0 || values.len() != dims * rows {
                    return Err(ClassifierError::Model(format!(
                        "unexpected embedding shape {shape:?}"
                    )));
                }
                Some((dims, values))
            } else {
                None
            };
            let mut offset = 0;
            for crop in batch {
                let count = self.runs_of(crop);
                let Some(runs) = probs.get(3 * offset..3 * (offset + count)) else {
                    return Err(ClassifierError::Model(format!(
                        "{} probabilities for {rows} runs",
                        probs.len() / 3
                    )));
                };
                let mut mean = [0.0f32; 3];
                for p in runs.chunks_exact(3) {
                    for k in 0..3 {
                        mean[k] += p[k] / count as f32;
                    }
                }
                let embeddings = match embeddings {
                    Some((dims, values)) => values[dims * offset..dims * (offset + count)]
                        .chunks_exact(dims)
                        .map(<[f32]>::to_vec)
                        .collect(),
                    None => Vec::new(),
                };
                offset += count;
                out.push(Embedded {
                    prediction: Prediction::new(mean),
                    embeddings,
                });
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_eight_turns_are_distinct_and_a_quarter_turn_is_counter_clockwise() {
        // 2 x 2: [a b; c d] turned a quarter counter-clockwise is [b d; a c] (numpy's rot90).
        let t = [1.0, 2.0, 3.0, 4.0];
        let mut out = Vec::new();
        shifted_turned(&t, 2, (0, 0), false, 1, &mut out);
        assert_eq!(out, [2.0, 4.0, 1.0, 3.0]);
        let mut all: Vec<Vec<f32>> = Vec::new();
        let t3: Vec<f32> = (0..9).map(|v| v as f32).collect();
        for (flip, k) in TURNS {
            let mut o = Vec::new();
            shifted_turned(&t3, 3, (0, 0), flip, k, &mut o);
            let mut sorted = o.clone();
            sorted.sort_by(f32::total_cmp);
            assert_eq!(sorted, t3, "a turn keeps every pixel");
            all.push(o);
        }
        all.sort_by(|a, b| a.partial_cmp(b).unwrap());
        all.dedup();
        assert_eq!(all.len(), 8);
    }

    #[test]
    fn a_shift_moves_rows_down_and_columns_right_wrapping_as_numpy_roll() {
        // 3 x 3, values 0..9 row by row; np.roll(x, (1, -1), axis=(0, 1)) is
        // [[7 8 6] [1 2 0] [4 5 3]].
        let t: Vec<f32> = (0..9).map(|v| v as f32).collect();
        let mut out = Vec::new();
        shifted_turned(&t, 3, (1, -1), false, 0, &mut out);
        assert_eq!(out, [7.0, 8.0, 6.0, 1.0, 2.0, 0.0, 4.0, 5.0, 3.0]);
        // Shifted first, then turned: the turn of the shifted crop.
        let mut shifted_then_turned = Vec::new();
        shifted_turned(&out, 3, (0, 0), true, 1, &mut shifted_then_turned);
        let mut both = Vec::new();
        shifted_turned(&t, 3, (1, -1), true, 1, &mut both);
        assert_eq!(both, shifted_then_turned);
    }

    #[test]
    fn rectangle_turns_keep_a_wide_shape_wide() {
        // A 3 x 3 crop whose middle row is lit (a long side along x): the rectangle turns are
        // exactly the turns of TURNS that leave it as it is.
        let t: Vec<f32> = (0..9)
            .map(|v| if (3..6).contains(&v) { 1.0 } else { 0.0 })
            .collect();
        let keeps = |flip: bool, k: u8| {
            let mut o = Vec::new();
            shifted_turned(&t, 3, (0, 0), flip, k, &mut o);
            o == t
        };
        let kept: Vec<(bool, u8)> = TURNS.into_iter().filter(|&(f, k)| keeps(f, k)).collect();
        assert_eq!(kept, RECTANGLE_TURNS);
    }
}

//! ONNX Runtime, loaded at run time: where its shared library is, one
//! process-wide environment, and the re-identification model that can give
//! DeepSORT its appearance descriptors.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use image::RgbImage;
use ort::environment::Environment;
use ort::session::Session;
use ort::value::TensorRef;
use towernav_geometry::PixelBox;

use towernav_core::detector::{ClassMap, CropBatch, Region};

#[derive(Debug, thiserror::Error)]
pub enum OnnxError {
    #[error(
        "no ONNX Runtime library found (looked in: {}); run `cargo xtask setup-ort` to install it \
         into .ort/lib, or set ORT_DYLIB_PATH to a libonnxruntime.so",
        searched.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
    )]
    NoLibrary { searched: Vec<PathBuf> },
    #[error("loading ONNX Runtime from {path}: {reason}")]
    Load { path: PathBuf, reason: String },
    #[error("model {path}: {reason}")]
    Model { path: PathBuf, reason: String },
    #[error("running model {path}: {reason}")]
    Run { path: PathBuf, reason: String },
}

/// `ORT_DYLIB_PATH` if set, else `.ort/lib/libonnxruntime.so` in the current
/// folder or any folder above it (the project's setup puts it there).
pub fn locate_runtime() -> Result<PathBuf, OnnxError> {
    let cwd = std::env::current_dir().unwrap_or_default();
    locate_runtime_from(std::env::var_os("ORT_DYLIB_PATH").map(PathBuf::from), &cwd)
}

/// `locate_runtime` with the variable's value and the starting folder given.
pub fn locate_runtime_from(
    dylib_path: Option<PathBuf>,
    start: &Path,
) -> Result<PathBuf, OnnxError> {
    let mut searched = Vec::new();
    if let Some(p) = dylib_path {
        if p.is_file() {
            return Ok(p);
        }
        searched.push(p);
    }
    for dir in start.ancestors() {
        let p = dir.join(".ort").join("lib").join("libonnxruntime.so");
        if p.is_file() {
            return Ok(p);
        }
        searched.push(p);
    }
    Err(OnnxError::NoLibrary { searched })
}

/// ONNX Runtime allows one environment per process: it lives here.
static RUNTIME: OnceLock<Result<(PathBuf, Environment), String>> = OnceLock::new();

/// Load ONNX Runtime once per process; later calls return the first outcome.
pub fn init_runtime() -> Result<&'static Environment, OnnxError> {
    let outcome = RUNTIME.get_or_init(|| {
        let path = locate_runtime().map_err(|e| e.to_string())?;
        let env = ort::init_from(&path)
            .map_err(|e| format!("loading ONNX Runtime from {}: {e}", path.display()))?
            .with_name("towernav")
            .build()
            .map_err(|e| format!("starting ONNX Runtime from {}: {e}", path.display()))?;
        Ok((path, env))
    });
    match outcome {
        Ok((_, env)) => Ok(env),
        Err(reason) => Err(OnnxError::Load {
            path: std::env::var_os("ORT_DYLIB_PATH")
                .map(PathBuf::from)
                .unwrap_or_default(),
            reason: reason.clone(),
        }),
    }
}

/// A session on the model at `path` with `threads` intra-op threads, on the
/// CUDA execution provider when asked (and built with the `cuda` feature).
pub fn load_session(path: &Path, threads: usize, cuda: bool) -> Result<Session, OnnxError> {
    let env = init_runtime()?;
    let bad = |reason: String| OnnxError::Model {
        path: path.to_path_buf(),
        reason,
    };
    let bytes = std::fs::read(path).map_err(|e| bad(format!("cannot read it: {e}")))?;
    let builder = Session::builder(env)
        .map_err(|e| bad(e.to_string()))?
        .with_intra_threads(threads.max(1))
        .map_err(|e| bad(e.to_string()))?
        // Threads that spin after a run steal the cores from the next
        // session's run (the detector's from the type classifier's).
        .with_intra_op_spinning(false)
        .map_err(|e| bad(e.to_string()))?;
    let mut builder = if cuda {
        with_cuda(builder).map_err(bad)?
    } else {
        builder
    };
    builder
        .commit_from_memory(&bytes)
        .map_err(|e| bad(format!("not a loadable ONNX model: {e}")))
}

/// The classes a model's `names` metadata lists, checked against the tower types.
pub fn model_classes(session: &Session, path: &Path) -> Result<ClassMap, OnnxError> {
    let bad = |reason: String| OnnxError::Model {
        path: path.to_path_buf(),
        reason,
    };
    let names = session
        .metadata()
        .map_err(|e| bad(format!("reading its metadata: {e}")))?
        .custom("names");
    ClassMap::from_metadata(names.as_deref()).map_err(|e| bad(e.to_string()))
}

/// The name and dimensions of a model's one input (`what`: what it should
/// hold, for the error when there is not exactly one).
pub fn only_input(
    session: &Session,
    path: &Path,
    what: &str,
) -> Result<(String, Vec<i64>), OnnxError> {
    let bad = |reason: String| OnnxError::Model {
        path: path.to_path_buf(),
        reason,
    };
    let [input] = session.inputs() else {
        return Err(bad(format!(
            "expected one input ({what}), found {}",
            session.inputs().len()
        )));
    };
    let dims = input
        .dtype()
        .tensor_shape()
        .map(|s| s.iter().copied().collect())
        .ok_or_else(|| bad("its input is not a tensor".into()))?;
    Ok((input.name().to_string(), dims))
}

#[cfg(feature = "cuda")]
fn with_cuda(
    builder: ort::session::builder::SessionBuilder,
) -> Result<ort::session::builder::SessionBuilder, String> {
    builder
        .with_execution_providers([ort::ep::CUDA::default().build()])
        .map_err(|e| format!("enabling CUDA: {e}"))
}

#[cfg(not(feature = "cuda"))]
fn with_cuda(
    _builder: ort::session::builder::SessionBuilder,
) -> Result<ort::session::builder::SessionBuilder, String> {
    Err(
        "CUDA was asked for, but towernav-edge was built without the `cuda` feature \
         (cargo build --features towernav-edge/cuda)"
            .into(),
    )
}

/// A re-identification model: crops [N, 3, H, W] (RGB in 0..1) in, one
/// embedding per crop out, L2-normalised here for cosine distance.
pub struct ReidModel {
    session: Session,
    path: PathBuf,
    input: String,
    height: u32,
    width: u32,
    crops: CropBatch,
}

impl ReidModel {
    pub fn load(path: &Path, threads: usize) -> Result<Self, OnnxError> {
        let session = load_session(path, threads, false)?;
        let bad = |reason: String| OnnxError::Model {
            path: path.to_path_buf(),
            reason,
        };
        let input = session
            .inputs()
            .first()
            .ok_or_else(|| bad("it has no inputs".into()))?;
        let dims: Vec<i64> = input
            .dtype()
            .tensor_shape()
            .map(|s| s.iter().copied().collect())
            .ok_or_else(|| bad("its input is not a tensor".into()))?;
        let (height, width) = match dims.as_slice() {
            [_, 3, h, w] if *h > 0 && *w > 0 => (*h as u32, *w as u32),
            other => {
                return Err(bad(format!(
                    "expected an input of shape [N, 3, H, W] with fixed H and W, found {other:?}"
                )));
            }
        };
        if session.outputs().len() != 1 {
            return Err(bad(format!(
                "expected one output (the embedding), found {}",
                session.outputs().len()
            )));
        }
        Ok(Self {
            input: input.name().to_string(),
            session,
            path: path.to_path_buf(),
            height,
            width,
            crops: CropBatch::new(width, height),
        })
    }

    /// One normalised embedding per box (boxes are clipped to the image).
    pub fn embed(
        &mut self,
        image: &RgbImage,
        boxes: &[PixelBox],
    ) -> Result<Vec<Vec<f32>>, OnnxError> {
        if boxes.is_empty() {
            return Ok(Vec::new());
        }
        let (h, w) = (self.height as usize, self.width as usize);
        let regions: Vec<Region> = boxes
            .iter()
            .map(|b| {
                let c = b.clipped(f64::from(image.width()), f64::from(image.height()));
                let (x0, y0) = (c.left.floor(), c.top.floor());
                Region {
                    left: x0 as i64,
                    top: y0 as i64,
                    width: ((c.right.ceil() - x0) as u32).max(1),
                    height: ((c.bottom.ceil() - y0) as u32).max(1),
                }
            })
            .collect();
        let fail = |reason: String| OnnxError::Run {
            path: self.path.clone(),
            reason,
        };
        let data = self
            .crops
            .cut(image, &regions)
            .map_err(|e| fail(e.to_string()))?;
        let tensor = TensorRef::from_array_view(([boxes.len(), 3, h, w], data))
            .map_err(|e| fail(e.to_string()))?;
        let outputs = self
            .session
            .run(ort::inputs![self.input.as_str() => tensor])
            .map_err(|e| fail(e.to_string()))?;
        let (shape, values) = outputs[0]
            .try_extract_tensor::<f32>()
            .map_err(|e| fail(format!("output is not float32: {e}")))?;
        let dim = match &**shape {
            [n, d] if *n as usize == boxes.len() && *d > 0 => *d as usize,
            other => return Err(fail(format!("expected output [N, D], got {other:?}"))),
        };
        Ok(values
            .chunks(dim)
            .map(|v| {
                let norm = v
                    .iter()
                    .map(|x| x * x)
                    .sum::<f32>()
                    .sqrt()
                    .max(f32::EPSILON);
                v.iter().map(|x| x / norm).collect()
            })
            .collect())
    }
}

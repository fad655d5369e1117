//! `cosim nn import`: a user's int8 ONNX network (DESIGN.md §18,
//! docs/NN_ONNX.md), as onnxruntime's `quantize_static` writes it (QDQ
//! format, per-channel int8 weights, int8 or uint8 activations), imported
//! into the model-as-data form a generic firmware on the GAP8 would read
//! ([`layers`]), and run by the host's integer reference ([`reference`]):
//! the arithmetic the deck's cluster kernels compute, not a run on the ISS.

pub mod deploy;
pub mod graph;
pub mod layers;
pub mod proto;
pub mod reference;
pub mod requant;

use npyz::WriterBuilder;
use std::path::{Path, PathBuf};

/// Why a file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum OnnxError {
    // The source follows in the error's chain (anyhow's "{:#}" prints
    // "path: source" on one line); naming it here too would repeat it.
    #[error("{}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: not an ONNX model", path.display())]
    Decode {
        path: PathBuf,
        source: prost::DecodeError,
    },
    #[error("{}", path.display())]
    Import {
        path: PathBuf,
        source: graph::ImportError,
    },
    #[error("{}: {why}", path.display())]
    Npy { path: PathBuf, why: String },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> OnnxError + '_ {
    move |source| OnnxError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Reads and imports an ONNX file.
pub fn import(path: &Path) -> Result<layers::Model, OnnxError> {
    use prost::Message;
    let bytes = std::fs::read(path).map_err(io_err(path))?;
    let m = proto::ModelProto::decode(&bytes[..]).map_err(|source| OnnxError::Decode {
        path: path.to_path_buf(),
        source,
    })?;
    let import_err = |source| OnnxError::Import {
        path: path.to_path_buf(),
        source,
    };
    let g = m
        .graph
        .as_ref()
        .ok_or_else(|| import_err(graph::ImportError::Model("the model has no graph".into())))?;
    graph::import_graph(g).map_err(import_err)
}

/// A float32 .npy file: its shape and values (C order).
pub fn read_npy_f32(path: &Path) -> Result<(Vec<usize>, Vec<f32>), OnnxError> {
    let file = std::fs::File::open(path).map_err(io_err(path))?;
    let npy = npyz::NpyFile::new(std::io::BufReader::new(file)).map_err(io_err(path))?;
    let npy_err = |why: String| OnnxError::Npy {
        path: path.to_path_buf(),
        why,
    };
    if npy.order() != npyz::Order::C {
        return Err(npy_err("Fortran order is not supported".into()));
    }
    let shape = npy.shape().iter().map(|&d| d as usize).collect();
    match npy.dtype() {
        npyz::DType::Plain(t) if t.to_string() == "<f4" => {}
        d => return Err(npy_err(format!("dtype {d:?}; float32 (<f4) is read"))),
    }
    let data = npy.into_vec::<f32>().map_err(io_err(path))?;
    Ok((shape, data))
}

/// Writes a float32 .npy file.
pub fn write_npy_f32(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), OnnxError> {
    let file = std::fs::File::create(path).map_err(io_err(path))?;
    let shape: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&shape)
        .writer(std::io::BufWriter::new(file))
        .begin_nd()
        .map_err(io_err(path))?;
    w.extend(data.iter().copied()).map_err(io_err(path))?;
    w.finish().map_err(io_err(path))
}

//! The subset of onnx.proto the importer reads, as `prost` messages with
//! the official field numbers, so that no protoc is needed. Fields not
//! listed here are skipped by the decoder (protobuf's unknown fields).
//!
//! onnx.proto is proto2: its `oneof`s (TypeProto.value,
//! TensorShapeProto.Dimension.value) are declared here as optional fields
//! with the same numbers, which decode the same bytes.

/// ModelProto.
#[derive(Clone, PartialEq, prost::Message)]
pub struct ModelProto {
    #[prost(int64, tag = "1")]
    pub ir_version: i64,
    #[prost(string, tag = "2")]
    pub producer_name: String,
    #[prost(string, tag = "3")]
    pub producer_version: String,
    #[prost(message, optional, tag = "7")]
    pub graph: Option<GraphProto>,
    #[prost(message, repeated, tag = "8")]
    pub opset_import: Vec<OperatorSetIdProto>,
}

/// OperatorSetIdProto.
#[derive(Clone, PartialEq, prost::Message)]
pub struct OperatorSetIdProto {
    #[prost(string, tag = "1")]
    pub domain: String,
    #[prost(int64, tag = "2")]
    pub version: i64,
}

/// GraphProto.
#[derive(Clone, PartialEq, prost::Message)]
pub struct GraphProto {
    #[prost(message, repeated, tag = "1")]
    pub node: Vec<NodeProto>,
    #[prost(string, tag = "2")]
    pub name: String,
    #[prost(message, repeated, tag = "5")]
    pub initializer: Vec<TensorProto>,
    #[prost(message, repeated, tag = "11")]
    pub input: Vec<ValueInfoProto>,
    #[prost(message, repeated, tag = "12")]
    pub output: Vec<ValueInfoProto>,
    #[prost(message, repeated, tag = "13")]
    pub value_info: Vec<ValueInfoProto>,
}

/// NodeProto.
#[derive(Clone, PartialEq, prost::Message)]
pub struct NodeProto {
    #[prost(string, repeated, tag = "1")]
    pub input: Vec<String>,
    #[prost(string, repeated, tag = "2")]
    pub output: Vec<String>,
    #[prost(string, tag = "3")]
    pub name: String,
    #[prost(string, tag = "4")]
    pub op_type: String,
    #[prost(message, repeated, tag = "5")]
    pub attribute: Vec<AttributeProto>,
    #[prost(string, tag = "7")]
    pub domain: String,
}

/// AttributeProto (the scalar, tensor and list forms the ops here use).
#[derive(Clone, PartialEq, prost::Message)]
pub struct AttributeProto {
    #[prost(string, tag = "1")]
    pub name: String,
    #[prost(float, tag = "2")]
    pub f: f32,
    #[prost(int64, tag = "3")]
    pub i: i64,
    #[prost(bytes = "vec", tag = "4")]
    pub s: Vec<u8>,
    #[prost(message, optional, tag = "5")]
    pub t: Option<TensorProto>,
    #[prost(float, repeated, tag = "7")]
    pub floats: Vec<f32>,
    #[prost(int64, repeated, tag = "8")]
    pub ints: Vec<i64>,
    /// AttributeProto.AttributeType: FLOAT 1, INT 2, STRING 3, TENSOR 4,
    /// FLOATS 6, INTS 7.
    #[prost(int32, tag = "20")]
    pub r#type: i32,
}

/// TensorProto.DataType values the importer reads.
pub mod data_type {
    pub const FLOAT: i32 = 1;
    pub const UINT8: i32 = 2;
    pub const INT8: i32 = 3;
    pub const INT32: i32 = 6;
    pub const INT64: i32 = 7;
}

/// TensorProto: initializers and constant attributes.
#[derive(Clone, PartialEq, prost::Message)]
pub struct TensorProto {
    #[prost(int64, repeated, tag = "1")]
    pub dims: Vec<i64>,
    #[prost(int32, tag = "2")]
    pub data_type: i32,
    #[prost(float, repeated, tag = "4")]
    pub float_data: Vec<f32>,
    /// int32, and int8/uint8 one value per element.
    #[prost(int32, repeated, tag = "5")]
    pub int32_data: Vec<i32>,
    #[prost(int64, repeated, tag = "7")]
    pub int64_data: Vec<i64>,
    #[prost(string, tag = "8")]
    pub name: String,
    /// Little-endian values, when the writer chose this form (onnxruntime's
    /// quantizer does).
    #[prost(bytes = "vec", tag = "9")]
    pub raw_data: Vec<u8>,
    /// TensorProto.DataLocation: 1 = EXTERNAL (data in another file; not
    /// read here).
    #[prost(int32, tag = "14")]
    pub data_location: i32,
}

/// ValueInfoProto.
#[derive(Clone, PartialEq, prost::Message)]
pub struct ValueInfoProto {
    #[prost(string, tag = "1")]
    pub name: String,
    #[prost(message, optional, tag = "2")]
    pub r#type: Option<TypeProto>,
}

/// TypeProto, its `tensor_type` member of the `value` oneof.
#[derive(Clone, PartialEq, prost::Message)]
pub struct TypeProto {
    #[prost(message, optional, tag = "1")]
    pub tensor_type: Option<TypeProtoTensor>,
}

/// TypeProto.Tensor.
#[derive(Clone, PartialEq, prost::Message)]
pub struct TypeProtoTensor {
    #[prost(int32, tag = "1")]
    pub elem_type: i32,
    #[prost(message, optional, tag = "2")]
    pub shape: Option<TensorShapeProto>,
}

/// TensorShapeProto.
#[derive(Clone, PartialEq, prost::Message)]
pub struct TensorShapeProto {
    #[prost(message, repeated, tag = "1")]
    pub dim: Vec<Dimension>,
}

/// TensorShapeProto.Dimension: a value or a symbolic name (a batch size).
#[derive(Clone, PartialEq, prost::Message)]
pub struct Dimension {
    #[prost(int64, optional, tag = "1")]
    pub dim_value: Option<i64>,
    #[prost(string, optional, tag = "2")]
    pub dim_param: Option<String>,
}

impl TensorProto {
    /// The element count its dims give.
    pub fn len(&self) -> usize {
        self.dims.iter().map(|&d| d.max(0) as usize).product()
    }

    /// Whether the tensor has no element.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The values as f64, whatever the stored form (raw little-endian bytes
    /// or the typed repeated field). `None` for a data type not read here.
    pub fn values(&self) -> Option<Vec<f64>> {
        let raw = &self.raw_data;
        let from_raw = !raw.is_empty();
        Some(match self.data_type {
            data_type::FLOAT if from_raw => raw
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64)
                .collect(),
            data_type::FLOAT => self.float_data.iter().map(|&v| v as f64).collect(),
            data_type::UINT8 if from_raw => raw.iter().map(|&v| v as f64).collect(),
            data_type::INT8 if from_raw => raw.iter().map(|&v| v as i8 as f64).collect(),
            data_type::UINT8 | data_type::INT8 | data_type::INT32 if !from_raw => {
                self.int32_data.iter().map(|&v| v as f64).collect()
            }
            data_type::INT32 => raw
                .chunks_exact(4)
                .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64)
                .collect(),
            data_type::INT64 if from_raw => raw
                .chunks_exact(8)
                .map(|b| i64::from_le_bytes(b.try_into().expect("8 bytes")) as f64)
                .collect(),
            data_type::INT64 => self.int64_data.iter().map(|&v| v as f64).collect(),
            _ => return None,
        })
    }
}

impl ValueInfoProto {
    /// The tensor's dimensions; a symbolic or missing one (a batch size)
    /// is `None`.
    pub fn dims(&self) -> Option<Vec<Option<i64>>> {
        let shape = self.r#type.as_ref()?.tensor_type.as_ref()?.shape.as_ref()?;
        Some(shape.dim.iter().map(|d| d.dim_value).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::Message;

    /// A NodeProto written byte by byte from onnx.proto's field numbers:
    /// input (1) "x", output (2) "y", name (3) "n", op_type (4) "Relu".
    #[test]
    fn node_fields_decode_by_their_official_numbers() {
        let bytes = [
            0x0a, 1, b'x', 0x12, 1, b'y', 0x1a, 1, b'n', 0x22, 4, b'R', b'e', b'l', b'u',
        ];
        let n = NodeProto::decode(&bytes[..]).unwrap();
        assert_eq!(n.input, ["x"]);
        assert_eq!(n.output, ["y"]);
        assert_eq!(n.name, "n");
        assert_eq!(n.op_type, "Relu");
    }

    /// dims written unpacked (proto2's default) and packed both decode;
    /// raw int8 data is read as signed.
    #[test]
    fn tensor_dims_packed_or_not_and_raw_int8() {
        // dims 2, 3 unpacked (tag 1 varint), data_type 3 (INT8),
        // raw_data (9) [0xff, 0x01, 0x80, 0, 2, 0x7f].
        let unpacked = [
            0x08, 2, 0x08, 3, 0x10, 3, 0x4a, 6, 0xff, 0x01, 0x80, 0, 2, 0x7f,
        ];
        let t = TensorProto::decode(&unpacked[..]).unwrap();
        assert_eq!(t.dims, [2, 3]);
        assert_eq!(t.len(), 6);
        assert_eq!(t.values().unwrap(), [-1.0, 1.0, -128.0, 0.0, 2.0, 127.0]);
        // dims packed: tag 1 length-delimited.
        let packed = [0x0a, 2, 2, 3, 0x10, 1, 0x22, 4, 0, 0, 0x80, 0x3f];
        let t = TensorProto::decode(&packed[..]).unwrap();
        assert_eq!(t.dims, [2, 3]);
        // float_data (4) packed: 1.0f32.
        assert_eq!(t.values().unwrap(), [1.0]);
    }

    /// A ValueInfoProto with a symbolic batch and 3 channels:
    /// name "in", type.tensor_type {elem_type 1, shape {dim {param "N"},
    /// dim {value 3}}}.
    #[test]
    fn value_info_shape_with_a_symbolic_dim() {
        let dim_n = [0x12, 1, b'N'];
        let dim_3 = [0x08, 3];
        let mut shape = vec![0x0a, dim_n.len() as u8];
        shape.extend(dim_n);
        shape.extend([0x0a, dim_3.len() as u8]);
        shape.extend(dim_3);
        let mut tensor = vec![0x08, 1, 0x12, shape.len() as u8];
        tensor.extend(&shape);
        let mut ty = vec![0x0a, tensor.len() as u8];
        ty.extend(&tensor);
        let mut vi = vec![0x0a, 2, b'i', b'n', 0x12, ty.len() as u8];
        vi.extend(&ty);
        let v = ValueInfoProto::decode(&vi[..]).unwrap();
        assert_eq!(v.name, "in");
        assert_eq!(v.dims().unwrap(), [None, Some(3)]);
    }
}

//! Small constructors of ONNX messages ([`super::proto`]) that every graph
//! we write uses: the policy exporter, the detector exporter and the tests
//! that build tiny models themselves.

use super::proto::*;

/// An f32 initializer `name` of shape `dims` (row-major `values`).
pub fn tensor(name: &str, dims: &[i64], values: &[f32]) -> TensorProto {
    TensorProto {
        dims: dims.to_vec(),
        data_type: data_type::FLOAT,
        name: name.into(),
        raw_data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

/// An attribute `name` of type `kind` with no value yet.
fn attribute(name: &str, kind: i32) -> AttributeProto {
    AttributeProto {
        name: name.into(),
        r#type: kind,
        ..Default::default()
    }
}

/// An attribute holding a list of integers.
pub fn ints(name: &str, v: &[i64]) -> AttributeProto {
    AttributeProto {
        ints: v.to_vec(),
        ..attribute(name, attribute_type::INTS)
    }
}

/// An attribute holding one integer.
pub fn int(name: &str, v: i64) -> AttributeProto {
    AttributeProto {
        i: Some(v),
        ..attribute(name, attribute_type::INT)
    }
}

/// An attribute holding one float.
pub fn float(name: &str, v: f32) -> AttributeProto {
    AttributeProto {
        f: Some(v),
        ..attribute(name, attribute_type::FLOAT)
    }
}

/// Node `name` of operator `op` (default domain) from `inputs` to `output`.
pub fn node(
    op: &str,
    name: &str,
    inputs: &[&str],
    output: &str,
    attribute: Vec<AttributeProto>,
) -> NodeProto {
    NodeProto {
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![output.to_string()],
        name: name.into(),
        op_type: op.into(),
        attribute,
        domain: String::new(),
    }
}

/// A graph input or output of f32 elements: each dimension fixed (`Ok`) or
/// symbolic (`Err("batch")`).
pub fn value_info(name: &str, dims: &[Result<i64, &str>]) -> ValueInfoProto {
    ValueInfoProto {
        name: name.into(),
        r#type: Some(TypeProto {
            tensor_type: Some(TypeProtoTensor {
                elem_type: data_type::FLOAT,
                shape: Some(TensorShapeProto {
                    dim: dims
                        .iter()
                        .map(|d| Dimension {
                            value: Some(match d {
                                Ok(v) => DimensionValue::DimValue(*v),
                                Err(p) => DimensionValue::DimParam(p.to_string()),
                            }),
                        })
                        .collect(),
                }),
            }),
        }),
        doc_string: String::new(),
    }
}

/// A model of `graph` made by deepfoids at ONNX IR `ir_version` and default
/// opset `opset`, with `doc_string` and the metadata `props` (key, value).
pub fn model(
    graph: GraphProto,
    ir_version: i64,
    opset: i64,
    doc_string: String,
    props: Vec<(String, String)>,
) -> ModelProto {
    ModelProto {
        ir_version,
        producer_name: "deepfoids".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        domain: String::new(),
        model_version: 1,
        doc_string,
        graph: Some(graph),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: opset,
        }],
        metadata_props: props
            .into_iter()
            .map(|(key, value)| StringStringEntryProto { key, value })
            .collect(),
    }
}

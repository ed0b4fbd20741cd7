//! Schemas of bodies that are not JSON, for the OpenAPI document.

use utoipa::ToSchema;

/// Binary glTF 2.0 (GLB) bytes.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct GlbBytes(#[allow(dead_code)] Vec<u8>);

/// A 3D Tiles 1.1 binary subtree file.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct SubtreeBytes(#[allow(dead_code)] Vec<u8>);

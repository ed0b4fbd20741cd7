//! How the vertex data of a GLB is stored: the choice a client makes with `?encoding=`.

use std::fmt;
use std::str::FromStr;

/// The storage of a GLB's vertices and triangles. All three describe the same triangles and
/// colours; they differ in bytes and in what a client must support.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
pub enum Encoding {
    /// Core glTF 2.0, no extension: f32 positions (and normals where stored), u8 colours,
    /// u16 or u32 indices. Every glTF reader loads it.
    #[default]
    Plain,
    /// `KHR_mesh_quantization`: positions as u16 in a box over the content (the node's matrix
    /// maps them back to metres; steps of the box's longest side / 65,535), normals as i8.
    Quantized,
    /// The quantized data, each buffer view compressed with `EXT_meshopt_compression`
    /// (meshoptimizer's vertex and index codecs, after reordering for the vertex cache). Clients
    /// need a meshopt decoder (three.js `MeshoptDecoder`, CesiumJS has one built in).
    Meshopt,
}

impl Encoding {
    pub const ALL: [Encoding; 3] = [Encoding::Plain, Encoding::Quantized, Encoding::Meshopt];

    /// The name used in URLs and cache keys.
    pub fn as_str(self) -> &'static str {
        match self {
            Encoding::Plain => "plain",
            Encoding::Quantized => "quantized",
            Encoding::Meshopt => "meshopt",
        }
    }

    /// Whether positions are stored as integers in a box.
    pub fn is_quantized(self) -> bool {
        self != Encoding::Plain
    }

    /// The glTF extensions a file in this encoding uses (and requires).
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            Encoding::Plain => &[],
            Encoding::Quantized => &["KHR_mesh_quantization"],
            Encoding::Meshopt => &["KHR_mesh_quantization", "EXT_meshopt_compression"],
        }
    }
}

impl fmt::Display for Encoding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The name is not one of `plain`, `quantized`, `meshopt`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown encoding {0:?}: use plain, quantized or meshopt")]
pub struct UnknownEncoding(pub String);

impl FromStr for Encoding {
    type Err = UnknownEncoding;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Encoding::ALL
            .into_iter()
            .find(|e| e.as_str() == s)
            .ok_or_else(|| UnknownEncoding(s.to_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for e in Encoding::ALL {
            assert_eq!(e.as_str().parse::<Encoding>(), Ok(e));
        }
        assert_eq!(
            "draco".parse::<Encoding>(),
            Err(UnknownEncoding("draco".to_owned()))
        );
    }
}

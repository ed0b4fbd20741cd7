//! The mesh every generator writes into, and its glTF/GLB encoding ([`gltf`]).
//!
//! Positions are `[east, north, up]` metres in a [`crate::geo::LocalFrame`]; triangles are
//! counter-clockwise seen from outside; every triangle carries a [`FaceStyle`] (flat shading).

pub mod check;
mod colour;
pub mod gltf;
pub mod manifold;

pub use check::{ClosedReport, check_closed};
pub use colour::Rgb;
pub use gltf::{EncodedGlb, Encoding, Placement, encode_glb};
pub use manifold::{ManifoldReport, Solids, check_manifold};

/// The cross product `(b - a) x (c - a)`: the normal of a counter-clockwise triangle, with twice
/// its area as length.
#[inline]
pub fn triangle_normal(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    [
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    ]
}

/// What a face is, which decides its glTF material.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Material {
    Ground,
    Wall,
    Roof,
    Floor,
}

impl Material {
    /// All materials, in the order the GLB lists them.
    pub const ALL: [Material; 4] = [
        Material::Ground,
        Material::Wall,
        Material::Roof,
        Material::Floor,
    ];

    /// The glTF material name.
    pub fn name(self) -> &'static str {
        match self {
            Material::Ground => "ground",
            Material::Wall => "wall",
            Material::Roof => "roof",
            Material::Floor => "floor",
        }
    }
}

/// The feature of a triangle that belongs to none (the ground).
pub const NO_FEATURE: u32 = u32::MAX;

/// Material, colour and feature of one triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FaceStyle {
    pub material: Material,
    pub colour: Rgb,
    /// The building the triangle belongs to: an index into the scene's feature list (the row
    /// of the GLB's property table), or [`NO_FEATURE`].
    pub feature: u32,
}

impl FaceStyle {
    /// A style that belongs to no feature.
    pub const fn plain(material: Material, colour: Rgb) -> Self {
        Self {
            material,
            colour,
            feature: NO_FEATURE,
        }
    }
}

/// An indexed triangle mesh in a local metric frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// `[east, north, up]` in metres.
    pub positions: Vec<[f64; 3]>,
    /// Counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// One entry per triangle.
    pub styles: Vec<FaceStyle>,
}

impl Mesh {
    /// Adds a vertex and returns its index.
    #[inline]
    pub fn push_vertex(&mut self, p: [f64; 3]) -> u32 {
        self.positions.push(p);
        (self.positions.len() - 1) as u32
    }

    /// Adds a triangle.
    #[inline]
    pub fn push_triangle(&mut self, t: [u32; 3], style: FaceStyle) {
        self.triangles.push(t);
        self.styles.push(style);
    }

    /// Room for the vertices and triangles of `parts` besides what is there.
    pub fn reserve_for<'a>(&mut self, parts: impl Iterator<Item = &'a Mesh> + Clone) {
        self.positions
            .reserve(parts.clone().map(|m| m.positions.len()).sum());
        self.triangles
            .reserve(parts.clone().map(|m| m.triangles.len()).sum());
        self.styles.reserve(parts.map(|m| m.styles.len()).sum());
    }

    /// Appends `other`'s vertices and triangles (its indices moved past this mesh's vertices).
    pub fn append(&mut self, other: &Mesh) {
        self.append_with_features(other, 0);
    }

    /// Appends `other` with its features numbered from `first_feature` on (parts of a scene
    /// built apart, each numbering its buildings from 0).
    pub fn append_with_features(&mut self, other: &Mesh, first_feature: u32) {
        let offset = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + offset)));
        self.styles.extend(other.styles.iter().map(|s| FaceStyle {
            feature: if s.feature == NO_FEATURE {
                NO_FEATURE
            } else {
                s.feature + first_feature
            },
            ..*s
        }));
    }

    /// The triangle's corner positions.
    #[inline]
    pub fn corners(&self, t: [u32; 3]) -> [[f64; 3]; 3] {
        t.map(|i| self.positions[i as usize])
    }
}

//! Typed cache keys: what a cached tile is (its scheme and coordinate), how it is encoded, and
//! which roof shapes went into it. Everything else its bytes depend on (generator version, DEM
//! and `--osm` files) is the cache's data version, fixed for a running server.

use citymesh_core::building::TagProperties;
use citymesh_core::geo::{GeoBbox, ImplicitTile, TileCoord};
/// How the bytes are encoded (the core's encodings: plain, quantized, meshopt).
pub use citymesh_core::mesh::Encoding;
use citymesh_core::scene::SceneArea;
use std::hash::{Hash, Hasher};

/// A box used as a key: equal when its four numbers are bit for bit equal.
#[derive(Debug, Clone, Copy)]
pub struct Region(pub GeoBbox);

impl Region {
    fn bits(&self) -> [u64; 4] {
        let b = &self.0;
        [b.min_lon(), b.min_lat(), b.max_lon(), b.max_lat()].map(f64::to_bits)
    }
}

impl PartialEq for Region {
    fn eq(&self, other: &Self) -> bool {
        self.bits() == other.bits()
    }
}

impl Eq for Region {}

impl Hash for Region {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.bits().hash(state);
    }
}

/// Which tile, in which scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TileId {
    /// A Web Mercator XYZ tile (`/tiles/{z}/{x}/{y}.glb`).
    Xyz(TileCoord),
    /// A content tile of the 3D Tiles implicit quadtree over `root`.
    Implicit { root: Region, tile: ImplicitTile },
    /// A box (`/scene`).
    Bbox(Region),
    /// A content tile of the world tileset (`/3dtiles/world/{z}/{x}/{y}.glb`).
    World(TileCoord),
}

impl TileId {
    /// The scheme's name, as stored.
    pub fn scheme(&self) -> &'static str {
        match self {
            TileId::Xyz(_) => "xyz",
            TileId::Implicit { .. } => "implicit",
            TileId::Bbox(_) => "bbox",
            // 2: leaves at zoom 15, content kept gzip-compressed (rows of the first tree, whose
            // zoom 14 drew buildings, are never read as this one's).
            TileId::World(_) => "world2",
        }
    }

    /// The area generated for this tile.
    pub fn area(&self) -> SceneArea {
        match *self {
            TileId::Xyz(t) => SceneArea::Xyz(t),
            TileId::Implicit { root, tile } => SceneArea::Implicit { root: root.0, tile },
            TileId::Bbox(b) => SceneArea::Bbox(b.0),
            TileId::World(t) => SceneArea::World(t),
        }
    }

    /// The ground the tile covers: a data change over it makes it stale.
    pub fn bounds(&self) -> GeoBbox {
        match self {
            TileId::Xyz(t) | TileId::World(t) => t.bounds(),
            TileId::Implicit { root, tile } => tile.bbox(&root.0).unwrap_or(root.0),
            TileId::Bbox(b) => b.0,
        }
    }
}

/// Where roof shapes come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum RoofSource {
    /// `roof:shape` tags, else the defaults.
    #[default]
    OsmTags,
    /// Tags, and for buildings without one the classifier's predictions: which model, and a
    /// digest of the predictions the tile's buildings have (so a new prediction changes the key of
    /// exactly the tiles holding its building).
    Classified { model: u64, predictions: u64 },
    /// Tags, and for buildings without one the roof prior's predictions: a digest of the priors
    /// used (each names its training data and settings).
    Inferred { priors: u64 },
}

impl RoofSource {
    /// The name stored with the tile: `osm`, `classified:<model>:<predictions>` or
    /// `inferred:<priors>`, in hex.
    pub fn name(self) -> String {
        match self {
            RoofSource::OsmTags => "osm".to_owned(),
            RoofSource::Classified { model, predictions } => {
                format!("classified:{model:016x}:{predictions:016x}")
            }
            RoofSource::Inferred { priors } => format!("inferred:{priors:016x}"),
        }
    }
}

/// A cached tile's key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TileKey {
    pub tile: TileId,
    pub encoding: Encoding,
    pub roofs: RoofSource,
    /// Whether each building carries every OSM tag too (`tags=all`).
    pub tags: TagProperties,
}

impl TileKey {
    /// An XYZ tile, plain, roofs from tags.
    pub fn xyz(t: TileCoord) -> Self {
        Self::new(TileId::Xyz(t))
    }

    /// A 3D Tiles content tile, plain, roofs from tags.
    pub fn implicit(root: GeoBbox, tile: ImplicitTile) -> Self {
        Self::new(TileId::Implicit {
            root: Region(root),
            tile,
        })
    }

    /// A content tile of the world tileset, plain, roofs from tags.
    pub fn world(t: TileCoord) -> Self {
        Self::new(TileId::World(t))
    }

    /// Whether the tile is kept gzip-compressed (`super::content_coding`): the world
    /// tileset's content, which browsers stream by the hundred.
    pub fn kept_gzipped(&self) -> bool {
        matches!(self.tile, TileId::World(_))
    }

    /// A box scene (`/scene`), plain, roofs from tags.
    pub fn bbox(b: GeoBbox) -> Self {
        Self::new(TileId::Bbox(Region(b)))
    }

    /// The same tile in `encoding`.
    pub fn with_encoding(self, encoding: Encoding) -> Self {
        Self { encoding, ..self }
    }

    /// The same tile with roofs from `roofs`.
    pub fn with_roofs(self, roofs: RoofSource) -> Self {
        Self { roofs, ..self }
    }

    /// The same tile, its buildings carrying the properties `tags` says.
    pub fn with_tags(self, tags: TagProperties) -> Self {
        Self { tags, ..self }
    }

    /// What the content is made of besides its area and encoding, as stored (the `roofs`
    /// column): the roof source's name, then `+tags` when every OSM tag is carried.
    pub fn content_name(&self) -> String {
        match self.tags {
            TagProperties::Named => self.roofs.name(),
            TagProperties::All => format!("{}+tags", self.roofs.name()),
        }
    }

    fn new(tile: TileId) -> Self {
        Self {
            tile,
            encoding: Encoding::default(),
            roofs: RoofSource::default(),
            tags: TagProperties::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_compare_by_their_numbers() {
        let a: GeoBbox = "8.39,49.04,8.41,49.06".parse().unwrap();
        let b: GeoBbox = "8.390,49.040,8.410,49.060".parse().unwrap();
        let c: GeoBbox = "8.39,49.04,8.41,49.0600001".parse().unwrap();
        let tile = ImplicitTile {
            level: 2,
            x: 1,
            y: 3,
        };
        assert_eq!(TileKey::implicit(a, tile), TileKey::implicit(b, tile));
        assert_ne!(TileKey::implicit(a, tile), TileKey::implicit(c, tile));
        let xyz = TileKey::xyz(TileCoord::new(16, 1, 2).unwrap());
        assert_eq!(xyz.tile.scheme(), "xyz");
        assert_ne!(xyz, TileKey::implicit(a, tile));
        let classified = |predictions| RoofSource::Classified {
            model: 0xab,
            predictions,
        };
        assert_ne!(xyz.with_roofs(classified(1)), xyz.with_roofs(classified(2)));
        assert_eq!(xyz.with_roofs(classified(1)), xyz.with_roofs(classified(1)));
        assert_eq!(
            classified(0x10).name(),
            "classified:00000000000000ab:0000000000000010"
        );
        assert_eq!(RoofSource::OsmTags.name(), "osm");
        assert_eq!(xyz.content_name(), "osm");
        let tagged = xyz.with_tags(TagProperties::All);
        assert_ne!(tagged, xyz);
        assert_eq!(tagged.content_name(), "osm+tags");
        assert_eq!(
            RoofSource::Inferred { priors: 0x2a }.name(),
            "inferred:000000000000002a"
        );
    }
}

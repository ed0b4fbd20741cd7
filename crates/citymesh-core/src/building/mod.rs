//! Buildings: from OSM building records to closed volumes in the local frame.
//!
//! Tags become parameters ([`tags`], [`params`], every default in [`defaults`]), counted from
//! the ground [`height_base`] says; the footprint
//! ([`footprint`]) gets its alternative coordinates ([`axes`]); a roof shape ([`roof`]) over the
//! virtual rectangle gives the roof surface ([`roof_surface`]), whose dividing segments cut the
//! footprint ([`boundary`]); the roof and floor are triangulated ([`triangulate`]) and walls added
//! ([`walls`]); touching volumes are meshed together without hidden walls ([`group`], grouped by
//! [`cluster`]). [`generate`] runs it all for one cluster and counts into [`stats`]; [`set`]
//! indexes a whole data set's clusters by area and tile; [`feature`] is what a client learns
//! when it picks a building.

pub mod axes;
pub mod boundary;
pub mod cluster;
pub mod coverage;
pub mod defaults;
pub mod feature;
pub mod footprint;
pub mod generate;
pub mod group;
pub mod height_base;
pub mod in_box;
mod length;
pub mod overlap;
pub mod params;
pub mod pieces;
pub mod roof;
pub mod roof_method;
pub mod roof_surface;
pub mod rules;
pub mod set;
pub mod skeleton_roof;
pub mod stats;
pub mod straight_skeleton;
mod sweep;
pub mod tags;
pub mod triangulate;
pub mod walls;

pub use cluster::clusters;
pub use feature::{BuildingFeature, RoofOrigin, TagProperties};
pub use generate::{BuildingContext, generate_cluster, generate_cluster_until};
pub use height_base::HeightBase;
pub use roof_method::RoofMethod;
pub use rules::BuildingRules;
pub use stats::BuildingStats;

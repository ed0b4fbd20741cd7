//! Buildings: from a building record to closed volumes in the local frame. Tags become parameters
//! ([`tags`], [`params`], with every default in [`defaults`]); the footprint gets its alternative
//! coordinates ([`axes`]); a roof shape ([`roof`]) gives the top; [`volume`] closes it all into a
//! watertight mesh.

pub mod axes;
pub mod defaults;
pub mod roof;
pub mod tags;

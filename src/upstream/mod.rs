//! Clients of upstream services. Overpass is the only one so far.

mod overpass;

pub use overpass::{
    DEFAULT_OVERPASS_URL, OverpassClient, OverpassConfig, OverpassError, building_query,
    check_complete,
};

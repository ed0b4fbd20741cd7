//! Every integration test of citymesh in one crate (one binary to build and link, as cargo's
//! own test suite is built): a module per concern, the shared helpers in [`common`].
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

mod common;

mod binary;
mod classifier;
mod classifier_real;
mod classify_adapt;
mod classify_area;
mod classify_box_rule;
mod classify_server;
mod classify_with_prior;
mod docs_limits;
mod export_command;
mod http_3dtiles;
mod http_abuse;
mod http_api;
mod http_buildings;
mod http_encodings;
mod http_errors;
mod http_ground;
mod http_procedural;
mod http_roofs_inferred;
mod http_serving;
mod http_slopes;
mod http_world;
mod import_abuse;
mod import_stream;
mod job_queue_backends;
mod replicas;
mod replication;
mod roof_prior;
mod scene_command;
mod storage_backends;

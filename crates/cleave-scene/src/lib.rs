//! cleave-scene: RON scenes, building exactly what a scene uses, running it and recording MCAP.
//! The only library crate that touches files (scene, meshes, recordings).

pub mod record;
pub mod run;
pub mod schema;

pub use record::{Recorder, EVENTS_TOPIC, STATS_TOPIC, SURFACE_TOPIC};
pub use run::{load_scene, BuildInfo, LoadedScene, SceneError, Simulation};
pub use schema::Scene;

//! cleave-scene: RON scenes, building exactly what a scene uses, running it and recording MCAP.
//! The only library crate that touches files (scene, meshes, recordings).

pub mod record;
pub mod run;
pub mod schema;

pub use cleave_integrator::StepReport;
pub use record::{EVENTS_TOPIC, Recorder, STATS_TOPIC, SURFACE_TOPIC};
pub use run::{BuildInfo, LoadedScene, SceneError, Simulation, load_scene};
pub use schema::Scene;

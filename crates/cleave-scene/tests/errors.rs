//! Bad scenes fail with clear messages: file:line:column for syntax and values, the mesh path and
//! the offending edge for meshes, never a panic.

use cleave_scene::run::parse_scene;
use cleave_scene::{SceneError, Simulation};
use std::path::Path;

const GOOD: &str = r#"// a small box
Scene(
    name: "box",
    object: Box(min: (0.0, 0.0, 0.0), max: (1.0, 0.5, 0.5)),
    material: (youngs_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000.0),
    backend: "voxel",
    settings: { "voxel": (cell_size: 0.25) },
    time_step: 0.01,
    steps: 3,
)
"#;

fn parse_error(text: &str) -> (usize, usize, String) {
    match parse_scene(Path::new("test.ron"), text) {
        Err(SceneError::Parse { line, column, message, .. }) => (line, column, message),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn the_reference_scene_parses_and_builds() {
    let loaded = parse_scene(Path::new("test.ron"), GOOD).unwrap();
    let mut simulation = Simulation::build(&loaded, None).unwrap();
    simulation.step().unwrap();
}

#[test]
fn unknown_field_names_its_line() {
    let text = GOOD.replace("    steps: 3,\n", "    steps: 3,\n    colour: \"red\",\n");
    let (line, _, message) = parse_error(&text);
    assert_eq!(line, 10, "{message}");
    assert!(message.contains("colour"), "{message}");
}

#[test]
fn malformed_value_names_its_line_and_column() {
    let text = GOOD.replace("time_step: 0.01", "time_step: \"fast\"");
    let (line, column, message) = parse_error(&text);
    assert_eq!(line, 8, "{message}");
    assert!(column > 5, "column {column}");
    let text = GOOD.replace("time_step: 0.01", "time_step: -0.01");
    let (line, _, message) = parse_error(&text);
    assert_eq!(line, 8);
    assert!(message.contains("-0.01"), "{message}");
}

#[test]
fn incompressible_material_is_rejected_with_the_value() {
    let text = GOOD.replace("poisson_ratio: 0.3", "poisson_ratio: 0.5");
    let (line, _, message) = parse_error(&text);
    assert_eq!(line, 5, "{message}");
    assert!(message.contains("Poisson ratio") && message.contains("0.5"), "{message}");
    let shown = parse_scene(Path::new("scenes/x.ron"), &text).unwrap_err().to_string();
    assert!(shown.starts_with("scenes/x.ron:5:"), "{shown}");
}

fn mesh_scene(mesh: &str) -> String {
    format!(
        r#"Scene(
    name: "mesh",
    object: Mesh(path: "{mesh}"),
    material: (youngs_modulus: 1.0e5, poisson_ratio: 0.3, density: 1000.0),
    backend: "voxel",
    settings: {{ "voxel": (cell_size: 0.25) }},
    time_step: 0.01,
    steps: 1,
)"#
    )
}

#[test]
fn missing_mesh_names_the_resolved_path() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.ron");
    let loaded = parse_scene(&scene, &mesh_scene("meshes/nowhere.obj")).unwrap();
    let error = Simulation::build(&loaded, None).err().expect("must fail");
    let message = error.to_string();
    assert!(matches!(error, SceneError::Mesh { .. }), "{message}");
    assert!(message.contains("meshes/nowhere.obj") && message.contains("cannot open"), "{message}");
}

#[test]
fn open_mesh_names_the_boundary_edge() {
    let dir = tempfile::tempdir().unwrap();
    // a unit cube with its last triangle (on the top face) removed
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
               f 1 3 2\nf 1 4 3\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\nf 5 6 7\n";
    std::fs::write(dir.path().join("open.obj"), obj).unwrap();
    let scene = dir.path().join("s.ron");
    let loaded = parse_scene(&scene, &mesh_scene("open.obj")).unwrap();
    let error = Simulation::build(&loaded, None).err().expect("must fail");
    let message = error.to_string();
    assert!(message.contains("open.obj"), "{message}");
    // the missing triangle (5, 7, 8) in 0-based indices is (4, 6, 7): its edges are open
    assert!(message.to_lowercase().contains("open") || message.contains("boundary"), "{message}");
    let edges_of_missing = ["(4, 6)", "(6, 4)", "(6, 7)", "(7, 6)", "(4, 7)", "(7, 4)"];
    assert!(edges_of_missing.iter().any(|edge| message.contains(edge)), "{message}");
}

#[test]
fn a_pinned_dg_body_cuts_and_keeps_its_clamp_on_the_held_piece() {
    // The clamp (weak u = 0 on the faces at x = 0) is kept by the cut: the held half stays,
    // the free half falls. The free piece makes the penalty search shift its check (docs/math/
    // dg.md §13.1); without it the rebuild would find no positive definite stiffness.
    let text = GOOD
        .replace(r#"backend: "voxel","#, r#"backend: "dg","#)
        .replace(r#""voxel": (cell_size: 0.25)"#, r#""dg": (cell_size: 0.25)"#)
        .replace(
            "    steps: 3,\n",
            "    steps: 3,\n    pins: [Region(min: (-0.01, -1.0, -1.0), max: (0.01, 1.0, 1.0))],\n    timeline: [Cut(time: 0.015, surface: Plane(point: (0.5, 0.0, 0.0), normal: (1.0, 0.0, 0.0)))],\n",
        );
    let loaded = parse_scene(Path::new("test.ron"), &text).unwrap();
    let mut simulation = Simulation::build(&loaded, None).unwrap();
    for _ in 0..3 {
        simulation.step().unwrap();
    }
    let summary = simulation.cut_summary();
    assert_eq!(summary.changes, 1);
    assert_eq!(summary.pieces.len(), 2, "the plane x = 0.5 parts the 4 × 2 × 2 cubes in two");
    for piece in &summary.pieces {
        assert!((piece.volume - 0.125).abs() < 1e-12, "{}", piece.volume);
    }
}

#[test]
fn refinement_on_a_backend_that_cannot_refine_is_a_build_error() {
    let text = GOOD.replace("    steps: 3,\n", "    steps: 3,\n    refinement: Some((stress: 1.0e3)),\n");
    let loaded = parse_scene(Path::new("test.ron"), &text).unwrap();
    let message = Simulation::build(&loaded, None).err().expect("voxel does not refine").to_string();
    assert!(message.contains("`refinement`") && message.contains("cannot refine"), "{message}");
}

#[test]
fn a_dg_box_refines_in_a_scene_keeping_its_volume() {
    // 4 × 2 × 2 cubes clamped at x = 0 sag under gravity: every cube is stressed above 1 µPa at
    // the first check, so 1→8 once (max depth 1) makes 16 × 8 elements.
    let text = GOOD
        .replace(r#"backend: "voxel","#, r#"backend: "dg","#)
        .replace(r#""voxel": (cell_size: 0.25)"#, r#""dg": (cell_size: 0.25, refine: (split: Octants, max_depth: 1))"#)
        .replace(
            "    steps: 3,\n",
            "    steps: 3,\n    pins: [Region(min: (-0.01, -1.0, -1.0), max: (0.01, 1.0, 1.0))],\n    refinement: Some((stress: 1.0e-6, every: 1)),\n",
        );
    let loaded = parse_scene(Path::new("test.ron"), &text).unwrap();
    let mut simulation = Simulation::build(&loaded, None).unwrap();
    for _ in 0..3 {
        simulation.step().unwrap();
    }
    let summary = simulation.cut_summary();
    assert_eq!(summary.changes, 1, "depth 1 stops after the first refinement");
    assert_eq!(summary.elements, 128);
    assert_eq!(summary.pieces.len(), 1);
    assert!((summary.pieces[0].volume - 0.25).abs() < 1e-12);
}

#[test]
fn a_bad_backend_setting_names_its_line_and_column_in_the_scene_file() {
    // The settings are read by the backend's registration after parsing; the error still points
    // into the scene file: line 7, at the misspelt field.
    let text = GOOD.replace("(cell_size: 0.25)", "(cell_sise: 0.25)");
    let loaded = parse_scene(Path::new("test.ron"), &text).unwrap();
    match Simulation::build(&loaded, None).err().expect("must fail") {
        SceneError::Parse { line, column, message, .. } => {
            assert_eq!(line, 7, "{message}");
            assert_eq!(column, 27, "{message}"); // the `c` of `cell_sise`
            assert!(message.contains("settings.voxel") && message.contains("cell_sise"), "{message}");
        }
        other => panic!("expected a positioned error, got {other}"),
    }
}

#[test]
fn unknown_backends_and_missing_settings_name_what_exists() {
    let loaded = parse_scene(Path::new("test.ron"), GOOD).unwrap();
    let message = Simulation::build_with_backend(&loaded, None, Some("fem9000")).err().expect("must fail").to_string();
    assert!(message.contains("fem9000") && message.contains("voxel") && message.contains("dg"), "{message}");
    let message = Simulation::build_with_backend(&loaded, None, Some("dg")).err().expect("must fail").to_string();
    assert!(message.contains("no entry for backend \"dg\"") && message.contains("voxel"), "{message}");
}

#[test]
fn a_cut_at_a_time_that_is_not_finite_is_a_clear_build_error() {
    for time in ["NaN", "inf"] {
        let text = GOOD.replace("backend: \"voxel\"", "backend: \"virtualnode\"").replace(
            "settings: { \"voxel\": (cell_size: 0.25) },",
            &format!(
                "settings: {{ \"virtualnode\": (cell_size: 0.25) }},\n    timeline: [Cut(time: {time}, surface: Plane(point: (0.5, 0.0, 0.0), normal: (1.0, 0.0, 0.0)))],"
            ),
        );
        let loaded = parse_scene(Path::new("test.ron"), &text).unwrap();
        let message = Simulation::build(&loaded, None).err().expect("must fail").to_string();
        assert!(message.contains("timeline[0]") && message.contains("must be finite"), "{time}: {message}");
    }
}

#[test]
fn a_mesh_the_backend_cannot_discretize_names_the_mesh_file() {
    // A closed unit cube voxelized at 0.1 mm would need 1e12 cells: the backend refuses it as a
    // mesh error (typed, not guessed from the message), and the scene names the OBJ file.
    let dir = tempfile::tempdir().unwrap();
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
               f 1 3 2\nf 1 4 3\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\nf 5 6 7\nf 5 7 8\n";
    std::fs::write(dir.path().join("cube.obj"), obj).unwrap();
    let scene = dir.path().join("s.ron");
    let text = mesh_scene("cube.obj").replace("cell_size: 0.25", "cell_size: 0.0001");
    let loaded = parse_scene(&scene, &text).unwrap();
    let error = Simulation::build(&loaded, None).err().expect("must fail");
    let message = error.to_string();
    assert!(matches!(error, SceneError::Mesh { .. }), "{message}");
    assert!(message.contains("cube.obj"), "{message}");
}

#[test]
fn fracture_needs_a_strength_and_a_backend_that_fractures() {
    let with_fracture = GOOD.replace("    steps: 3,\n", "    steps: 3,\n    fracture: (every: 1),\n");
    let loaded = parse_scene(Path::new("test.ron"), &with_fracture).unwrap();
    let message = Simulation::build(&loaded, None).err().expect("no strength").to_string();
    assert!(message.contains("tensile_strength"), "{message}");
    let strong = with_fracture.replace("density: 1000.0)", "density: 1000.0, tensile_strength: 5e4)");
    let loaded = parse_scene(Path::new("test.ron"), &strong).unwrap();
    let mut simulation = Simulation::build(&loaded, None).unwrap();
    simulation.step().unwrap();
    let dg = strong
        .replace(r#"backend: "voxel","#, r#"backend: "dg","#)
        .replace(r#""voxel": (cell_size: 0.25)"#, r#""dg": (cell_size: 0.25)"#);
    let loaded = parse_scene(Path::new("test.ron"), &dg).unwrap();
    let message = Simulation::build(&loaded, None).err().expect("dg cannot fracture").to_string();
    assert!(message.contains("cannot fracture"), "{message}");
    // A strength that is not positive is refused while parsing, with its position.
    let weak = with_fracture.replace("density: 1000.0)", "density: 1000.0, tensile_strength: -1.0)");
    let (line, _, message) = parse_error(&weak);
    assert_eq!(line, 5, "{message}");
    assert!(message.contains("tensile strength"), "{message}");
}

#[test]
fn a_solver_for_a_backend_without_settings_is_a_build_error() {
    let text = GOOD.replace("    steps: 3,\n", "    steps: 3,\n    solver_for: { \"dg\": Cholesky },\n");
    let loaded = parse_scene(Path::new("test.ron"), &text).unwrap();
    let message = Simulation::build(&loaded, None).err().expect("dg has no settings").to_string();
    assert!(message.contains("solver_for") && message.contains("\"dg\""), "{message}");
    // With the backend's own entry it builds and steps.
    let text = GOOD.replace("    steps: 3,\n", "    steps: 3,\n    solver_for: { \"voxel\": Cholesky },\n");
    let loaded = parse_scene(Path::new("test.ron"), &text).unwrap();
    Simulation::build(&loaded, None).unwrap().step().unwrap();
}

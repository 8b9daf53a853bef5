//! Every registered backend advertises what its scene-built solid can do: its capabilities,
//! read off the comparison box it builds, agree with what `as_cuttable`, `as_fracturable` and
//! `as_refinable` answer on the solid a scene asks it for (a box, through its own settings).

use cleave_core::Material;
use cleave_registry::{Region, Shape, SolidRequest, names, registered};

/// Scene settings of each backend for a coarse box (two cells along x).
fn settings(name: &str) -> &'static str {
    match name {
        "voxel" => "(cell_size: 0.5)",
        "dg" => "(cell_size: 0.5)",
        "virtualnode" => "(cell_size: 0.5)",
        "meanvalue" => "(cell_size: 0.5)",
        other => panic!("give the registration test scene settings for the new backend {other:?}"),
    }
}

#[test]
fn what_every_backend_advertises_is_what_its_solid_can_do() {
    let material = Material::new(1e5, 0.3, 1000.0).unwrap();
    let pins: [Region; 0] = [];
    let request = SolidRequest { shape: Shape::Box { min: [0.0; 3], max: [1.0, 0.5, 0.5] }, material, pins: &pins };
    assert_eq!(names().len(), registered().len());
    for backend in registered() {
        let advertised = backend.capabilities();
        let mut built = backend.build_solid(settings(backend.name()), &request).unwrap();
        let d = built.discretization.as_mut();
        let (cut, fracture, refine) =
            (d.as_cuttable().is_some(), d.as_fracturable().is_some(), d.as_refinable().is_some());
        println!("{}: cut {cut}, fracture {fracture}, refine {refine}", backend.name());
        assert_eq!(advertised.cut, cut, "{}: advertised cut", backend.name());
        assert_eq!(advertised.fracture, fracture, "{}: advertised fracture", backend.name());
        assert_eq!(advertised.refine, refine, "{}: advertised refine", backend.name());
        // A backend whose solids cut must run the cut problems of the comparison in every variant.
        if cut {
            for variant in backend.variants() {
                assert!(backend.cuts(&variant), "{}/{variant} cuts in scenes but not in comparisons", backend.name());
            }
        }
    }
}

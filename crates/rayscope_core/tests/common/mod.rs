//! Scene files built in code, shared by the core's integration tests and its benchmarks.

use rayscope_scene::{EntityDef, MaterialDef, MaterialKind, SceneFile, Shape};

/// A scene file of `shapes`, one entity each (`E0`, `E1`, …), all of one white diffuse material.
pub fn one_material_file(shapes: Vec<Shape>) -> SceneFile {
    SceneFile {
        materials: vec![MaterialDef {
            name: "M".into(),
            kind: MaterialKind::Diffuse,
            color: glam::DVec3::ONE,
            value: 1.0,
            line: 1,
        }],
        entities: shapes
            .into_iter()
            .enumerate()
            .map(|(i, shape)| EntityDef {
                name: format!("E{i}"),
                shape,
                material: 0,
                line: i + 2,
            })
            .collect(),
        ..SceneFile::default()
    }
}

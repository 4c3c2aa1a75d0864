//! The course's reference scenes and the Stanford bunny parse to exactly what the text says.

use rayscope_scene::{load, load_obj, DVec3, MaterialKind, ObjOptions, Shape, Vec3};
use rayscope_testkit::course;

#[test]
fn sample_scene_1() {
    let Some(c) = course() else { return };
    let scene = load(&c.scene("sample_scene_1.txt")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.materials.len(), 3);
    assert_eq!(scene.lights.len(), 1);
    assert_eq!(scene.entities.len(), 3);

    let red = &scene.materials[0];
    assert_eq!(red.name, "Red");
    assert_eq!(red.kind, MaterialKind::Diffuse);
    assert_eq!(red.color, DVec3::new(1.0, 0.5, 0.5));
    assert_eq!(red.value, 1.0);
    assert_eq!(red.line, 2); // the file starts with a blank line

    let light = &scene.lights[0];
    assert_eq!(light.name, "Light");
    assert_eq!(light.position, DVec3::new(0.75, 1.0, 0.0));
    assert_eq!(light.color, DVec3::ONE);
    assert_eq!(light.line, 6);

    let plane = &scene.entities[0];
    assert_eq!(plane.name, "Plane");
    assert_eq!(plane.material, 0);
    assert_eq!(
        plane.shape,
        Shape::Plane {
            point: DVec3::new(0.0, -1.0, 0.0),
            normal: DVec3::Y
        }
    );
    assert_eq!(
        scene.entities[1].shape,
        Shape::Sphere {
            center: DVec3::new(-0.25, 0.0, 2.0),
            radius: 0.5
        }
    );
    assert_eq!(scene.entities[1].material, 1);
    assert_eq!(
        scene.entities[2].shape,
        Shape::Triangle {
            vertices: [
                DVec3::new(0.45, -0.05, 1.75),
                DVec3::new(0.7, 0.25, 2.5),
                DVec3::new(0.95, -0.1, 2.0)
            ]
        }
    );
    assert_eq!(scene.entities[2].material, 2);
    assert_eq!(scene.entities[2].line, 10);
}

#[test]
fn sample_scene_2() {
    let Some(c) = course() else { return };
    let scene = load(&c.scene("sample_scene_2.txt")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.materials.len(), 6);
    assert_eq!(scene.lights.len(), 2);
    assert_eq!(scene.entities.len(), 12);

    let glass = &scene.materials[4];
    assert_eq!(glass.name, "GlassMat");
    assert_eq!(glass.kind, MaterialKind::Refractive);
    assert_eq!(glass.color, DVec3::ZERO);
    assert_eq!(glass.value, 1.4);
    assert_eq!(scene.materials[5].kind, MaterialKind::Reflective);

    let mirror = &scene.entities[0];
    assert_eq!(mirror.name, "MirrorSphere");
    assert_eq!(scene.materials[mirror.material].name, "MirrorMat");
    let roof = &scene.entities[3];
    assert_eq!(roof.name, "Roof");
    assert_eq!(
        roof.shape,
        Shape::Plane {
            point: DVec3::Y,
            normal: -DVec3::Y
        }
    );
    let last = scene.entities.last().unwrap();
    assert_eq!(last.name, "FarWallB");
    assert_eq!(last.shape.command(), "Triangle");
    assert_eq!(scene.materials[last.material].name, "BlueMat");
}

#[test]
fn sample_scene_2_2021_differs_only_in_colours() {
    let Some(c) = course() else { return };
    let a = load(&c.scene("sample_scene_2.txt")).unwrap();
    let b = load(&c.scene("sample_scene_2_2021.txt")).unwrap();
    assert_eq!(a.entities, b.entities);
    assert_eq!(b.materials[4].color, DVec3::ONE);
    assert_eq!(b.materials[5].color, DVec3::ONE);
}

/// The scene names its OBJ relative to the course's folder; from this crate's directory (the
/// working directory of tests) it is found through the scene folder's ancestors.
#[test]
fn sample_scene_obj_finds_the_bunny() {
    let Some(c) = course() else { return };
    let scene = load(&c.scene("sample_scene_obj.txt")).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.materials.len(), 5);
    assert_eq!(scene.lights.len(), 2);
    assert_eq!(scene.entities.len(), 11);
    let bunny = &scene.entities[0];
    assert_eq!(bunny.name, "Bunny");
    assert_eq!(scene.materials[bunny.material].name, "BunnyMat");
    let Shape::Mesh {
        source,
        offset,
        scale,
        mesh,
    } = &bunny.shape
    else {
        panic!("not a mesh: {:?}", bunny.shape.command());
    };
    assert_eq!(source, &std::fs::canonicalize(c.scene("models/bunny.obj")).unwrap());
    assert_eq!(*offset, DVec3::new(0.0, -0.9, 2.0));
    assert_eq!(*scale, 0.35);
    assert_eq!(mesh.triangles.len(), 4968);
}

#[test]
fn bunny_mesh() {
    let Some(c) = course() else { return };
    let opts = ObjOptions {
        scale: 0.35,
        offset: DVec3::new(0.0, -0.9, 2.0),
    };
    let mesh = load_obj(&c.scene("models/bunny.obj"), &opts).unwrap();
    assert_eq!(mesh.triangles.len(), 4968);
    assert_eq!(mesh.positions.len(), 2503);
    assert_eq!(mesh.normals.len(), 2503);
    // v -0.613298 1.076979 0.002881
    let expected = DVec3::new(0.35 * -0.613298, 0.35 * 1.076979 - 0.9, -0.35 * 0.002881 + 2.0).as_vec3();
    assert_eq!(mesh.positions[0], expected);
    // vn -0.865291 0.093722 -0.492386, z negated and normalised.
    let n = Vec3::new(-0.865291, 0.093722, 0.492386).normalize();
    assert!((mesh.normals[0] - n).length() < 1e-6);
    assert!(mesh.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
    // f 1//1 2//2 3//3
    assert_eq!(mesh.triangles[0].positions, [0, 1, 2]);
    assert_eq!(mesh.triangles[0].normals, Some([0, 1, 2]));
    assert!(mesh.triangles.iter().all(|t| t.normals.is_some()));
}

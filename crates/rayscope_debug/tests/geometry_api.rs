//! What the inspector and the view need to let a student check geometry by eye: a triangle's
//! normal (the course's winding), a plane's unit normal, and normals drawn as arrows.

mod common;

use common::{request, start_server, wait_for_render};

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/whitted.txt");

fn entity<'a>(scene: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    scene["entities"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"] == name)
        .unwrap_or_else(|| panic!("no entity {name}"))
}

fn v3(v: &serde_json::Value) -> [f64; 3] {
    std::array::from_fn(|i| v[i].as_f64().unwrap())
}

#[test]
fn the_scene_api_gives_triangle_and_plane_normals() {
    let server = start_server(SCENE, 40, 30);
    let (code, body) = request(server.addr, "GET", "/api/scene", b"");
    assert_eq!(code, 200);
    let s: serde_json::Value = serde_json::from_slice(&body).unwrap();

    let p = &entity(&s, "PyrA")["params"];
    let (a, b, c) = (v3(&p["v0"]), v3(&p["v1"]), v3(&p["v2"]));
    let (e1, e2) = (
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
        [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
    );
    let cross = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let len = cross.iter().map(|x| x * x).sum::<f64>().sqrt();
    let n = v3(&p["normal"]);
    for i in 0..3 {
        assert!(
            (n[i] - cross[i] / len).abs() < 1e-12,
            "(v1 − v0) × (v2 − v0), normalised"
        );
    }
    // PyrA is a face of a tetrahedron: (v1 − v0) × (v2 − v0) points out of it, away from the
    // apex-to-base centre of the other faces' vertices.
    let all: Vec<[f64; 3]> = ["PyrA", "PyrB", "PyrC"]
        .iter()
        .flat_map(|name| {
            let p = &entity(&s, name)["params"];
            [v3(&p["v0"]), v3(&p["v1"]), v3(&p["v2"])]
        })
        .collect();
    let centre: [f64; 3] = std::array::from_fn(|i| all.iter().map(|v| v[i]).sum::<f64>() / all.len() as f64);
    let face: [f64; 3] = std::array::from_fn(|i| (a[i] + b[i] + c[i]) / 3.0 - centre[i]);
    assert!(n.iter().zip(face).map(|(x, y)| x * y).sum::<f64>() > 0.0, "outward");

    let wall = &entity(&s, "Wall")["params"];
    assert_eq!(v3(&wall["unit_normal"]), [0.0, 0.0, -1.0]);
}

#[test]
fn the_view_draws_the_selected_entitys_normals_on_request() {
    let server = start_server(SCENE, 40, 30);
    wait_for_render(server.addr);
    let (code, body) = request(server.addr, "GET", "/api/scene", b"");
    assert_eq!(code, 200);
    let s: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let ball = entity(&s, "GlassBall")["index"].as_u64().unwrap();
    let view = |extra: &str| {
        let path = format!("/api/view?w=240&h=160&rays=none&image=none&format=png&select=entity:{ball}{extra}");
        let (code, png) = request(server.addr, "GET", &path, b"");
        assert_eq!(code, 200, "{}", String::from_utf8_lossy(&png));
        image::load_from_memory(&png).unwrap().to_rgb8()
    };
    let yellow = |img: &image::RgbImage| {
        img.pixels()
            .filter(|p| p.0[0] > 200 && p.0[1] > 180 && p.0[2] < 90)
            .count()
    };
    let without = view("");
    let with = view("&normals=1");
    assert!(
        yellow(&with) > yellow(&without) + 30,
        "{} vs {}",
        yellow(&with),
        yellow(&without)
    );
}

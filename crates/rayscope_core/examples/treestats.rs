fn visits(scene: &rayscope_core::scene::Scene, file: &str) {
    let bytes = std::fs::read(file).unwrap();
    let f: Vec<f32> = bytes
        .chunks(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let (mut total, mut hits, mut hv, mut n) = (0u64, 0u64, 0u64, 0u64);
    for r in f.chunks(6) {
        let ray = rayscope_core::math::Ray::new(glam::Vec3A::new(r[0], r[1], r[2]), glam::Vec3A::new(r[3], r[4], r[5]));
        let mut v = 0u32;
        let h = scene.wide.closest::<true>(&ray, 0.0, f32::INFINITY, &mut v);
        total += v as u64;
        n += 1;
        if h.is_some() {
            hits += 1;
            hv += v as u64;
        }
    }
    println!(
        "{file}: visits/ray {:.2}, hits {hits}, visits/hitting ray {:.2}",
        total as f64 / n as f64,
        hv as f64 / hits as f64
    );
}
fn leaf_depths(w: &rayscope_core::wide::Bvh4, r: u32, d: u32, out: &mut Vec<u32>) {
    if r == u32::MAX {
        return;
    }
    if r & (1 << 31) != 0 {
        out.push(d);
        return;
    }
    for &c in &w.nodes[r as usize].children {
        leaf_depths(w, c, d + 1, out);
    }
}
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let file = rayscope_scene::load(std::path::Path::new(&path)).unwrap();
    let scene = rayscope_core::scene::Scene::from_file(&file);
    let w = &scene.wide;
    let tris = scene.primitive_count();
    let filled: usize = w
        .tris
        .iter()
        .map(|p| p.ids.iter().filter(|&&i| i != u32::MAX).count())
        .sum();
    let mut valid_hist = [0usize; 5];
    for n in &w.nodes {
        valid_hist[n.valid.count_ones() as usize] += 1;
    }
    println!(
        "prims {tris} nodes {} packets {} filled {} avg fill {:.2} depth {} node children hist {:?} bytes/tri {:.1}",
        w.nodes.len(),
        w.tris.len(),
        filled,
        filled as f64 / w.tris.len() as f64,
        w.depth(),
        valid_hist,
        w.memory_bytes() as f64 / tris as f64
    );
    let mut ds = Vec::new();
    leaf_depths(w, w.root, 0, &mut ds);
    let mut hist = [0usize; 20];
    for &d in &ds {
        hist[d as usize] += 1;
    }
    println!(
        "leaves {} avg depth {:.2} hist {:?}",
        ds.len(),
        ds.iter().map(|&d| d as f64).sum::<f64>() / ds.len() as f64,
        &hist[..14]
    );
    for f in std::env::args().skip(2) {
        visits(&scene, &f);
    }
}

//! What a scene means in each edition of the course ([`Edition`]): the editions differ in one
//! thing, a Refractive material's colour, which the 2021 course ignored and the 2022 course reads
//! as Beer's-law absorbance. A scene that colours its glass and uses nothing else of stage 3 may
//! have been written for either, so a render says which reading it took.

use rayscope_scene::{MaterialKind, SceneFile, Shape};

use crate::material::{Lobe, Material};
use crate::settings::{Edition, RenderSettings, Stage};

/// The first Refractive material an entity uses whose colour is not black, if any.
fn coloured_glass(file: &SceneFile) -> Option<&rayscope_scene::MaterialDef> {
    file.entities
        .iter()
        .map(|e| &file.materials[e.material])
        .find(|m| m.kind == MaterialKind::Refractive && m.color != glam::DVec3::ZERO)
}

/// True when the edition changes a render of `file` at `settings`: the scene's glass is
/// coloured and the render is the full one (stage 2 glass is clear in both editions).
#[must_use]
pub fn edition_matters(file: &SceneFile, settings: &RenderSettings) -> bool {
    settings.stage == Stage::Full && coloured_glass(file).is_some()
}

/// True when the scene or the flags use a stage-3 add-on other than Beer's law: emissive
/// surfaces or reflection models other than Lambert's, OBJ models, `-l`, a moved or turned camera, or depth of field.
fn other_stage_3(file: &SceneFile, s: &RenderSettings) -> bool {
    let materials = file.entities.iter().any(|e| {
        matches!(
            Material::from_def(&file.materials[e.material]).lobe(),
            Lobe::Emitter | Lobe::Bsdf
        )
    });
    let meshes = file.entities.iter().any(|e| matches!(e.shape, Shape::Mesh { .. }));
    let c = &s.camera;
    let camera = c.position != glam::Vec3::ZERO || c.angle_deg != 0.0 || c.aperture_radius > 0.0;
    materials || meshes || s.ambient || camera
}

/// The note a render of `file` at `settings` prints first when the scene gives glass a colour
/// and uses nothing else of stage 3: which edition's reading of that colour it used, and the
/// flag for the other. None when the reading is not in doubt.
#[must_use]
pub fn glass_colour_note(file: &SceneFile, settings: &RenderSettings) -> Option<String> {
    if !edition_matters(file, settings) || other_stage_3(file, settings) {
        return None;
    }
    let m = coloured_glass(file)?;
    let colour = format!("({}, {}, {})", m.color.x, m.color.y, m.color.z);
    Some(match settings.edition {
        Edition::Y2022 => format!(
            "note: glass '{}' has colour {colour}, read as the 2022 course reads it: Beer's-law absorbance (stage 3 F), which darkens the glass; in the 2021 course the glass colour played no part: pass --edition 2021 (or --stage 2) for that reading",
            m.name
        ),
        Edition::Y2021 => format!(
            "note: glass '{}' has colour {colour}, read as the 2021 course reads it: the colour plays no part (clear glass); pass --edition 2022 to read it as Beer's-law absorbance (stage 3 F)",
            m.name
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(text: &str) -> SceneFile {
        rayscope_scene::parse_str(text, std::path::Path::new("t.txt")).unwrap()
    }

    const GLASS: &str = "Material \"G\" Refractive (1, 1, 1) 1.4\nMaterial \"W\" Diffuse (1, 1, 1) 1\nSphere \"S\" (0, 0, 5) 1 \"G\"\nPlane \"P\" (0, -1, 0) (0, 1, 0) \"W\"\nPointLight \"L\" (0, 2, 0) (1, 1, 1)\n";

    #[test]
    fn coloured_glass_alone_gets_a_note_naming_the_other_reading() {
        let f = scene(GLASS);
        let s = RenderSettings::default();
        let note = glass_colour_note(&f, &s).unwrap();
        assert!(note.contains("2022") && note.contains("--edition 2021"), "{note}");
        let old = RenderSettings {
            edition: Edition::Y2021,
            ..s
        };
        let note = glass_colour_note(&f, &old).unwrap();
        assert!(note.contains("--edition 2022"), "{note}");
        let two = RenderSettings { stage: Stage::Two, ..s };
        assert_eq!(
            glass_colour_note(&f, &two),
            None,
            "stage 2 glass is clear in both editions"
        );
        let lit = RenderSettings { ambient: true, ..s };
        assert_eq!(glass_colour_note(&f, &lit), None, "-l is stage 3: Beer's law is meant");
        let clear = scene(&GLASS.replace("(1, 1, 1) 1.4", "(0, 0, 0) 1.4"));
        assert_eq!(glass_colour_note(&clear, &s), None);
        let glowing = scene(&format!(
            "{GLASS}Material \"E\" Emissive (1, 1, 1) 1\nSphere \"E\" (2, 0, 5) 0.5 \"E\"\n"
        ));
        assert_eq!(glass_colour_note(&glowing, &s), None);
    }
}

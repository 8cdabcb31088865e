//! Light layers: every baked light in one named group, so that an engine
//! can dim, switch and tint each group at run time.
//!
//! Diffuse light transport is linear in the emitters: with the lights
//! split into layers, the bake of any intensities of the layers is the
//! same weighted sum of the layers' bakes, bounces included. A punctual
//! light's layer is its node's `extras.radbake.layer`, an emissive
//! surface's its material's, the sky's the `sky_layer` setting; anything
//! that names none is in [`STATIC_LAYER`].

use crate::config::{BakeConfig, LayerMode, LightMode, LIVE_LAYER, STATIC_LAYER};
use crate::error::{Error, Result};
use crate::scene::Scene;

/// The layers of a scene, and what each light belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct Layers {
    /// The names: [`STATIC_LAYER`] first where anything is in it, then the
    /// others in alphabetical order. Only layers that hold a light.
    pub names: Vec<String>,
    /// Per scene light ([`Scene::lights`]): its layer (`None`: a realtime
    /// light, which is not baked).
    pub light: Vec<Option<usize>>,
    /// Per material: the layer of its emission (`None`: it emits nothing).
    pub material: Vec<Option<usize>>,
    /// The sky's layer (`None`: the sky is black).
    pub sky: Option<usize>,
}

impl Layers {
    /// How many layers.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True when nothing is in any layer (nothing emits).
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// What layer `k` holds, by name: its lights (by light name) and its
    /// emissive materials (by material name), and whether the sky.
    pub fn members(&self, scene: &Scene, k: usize) -> (Vec<String>, Vec<String>, bool) {
        let lights = (scene.lights.iter().zip(&self.light))
            .filter(|(_, l)| **l == Some(k))
            .map(|(l, _)| l.name.clone())
            .collect();
        let materials = (scene.materials.iter().zip(&self.material))
            .filter(|(_, m)| **m == Some(k))
            .map(|(m, _)| m.name.clone())
            .collect();
        (lights, materials, self.sky == Some(k))
    }
}

/// The scene's layers under `config`: `None` with `layers = "off"`, or
/// where neither the scene (a light's node or a material) nor `sky_layer`
/// names one (the bake is then the one lightmap of every light, as without
/// layers). `sky_black`: the sky gives no light (it is then in no layer).
/// Call after the light modes are applied
/// ([`crate::config::LightModes::apply`]).
///
/// # Errors
/// [`Error::Config`] for a layer on a `realtime` light (it is not baked:
/// the layer would hold nothing of it).
pub fn resolve(scene: &Scene, config: &BakeConfig, sky_black: bool) -> Result<Option<Layers>> {
    let named = scene
        .lights
        .iter()
        .any(|l| l.layer.is_some() || l.mode == LightMode::Live)
        || scene.materials.iter().any(|m| m.layer.is_some())
        || config.sky_layer.is_some();
    if config.layers == LayerMode::Off || !named {
        return Ok(None);
    }
    if let Some(l) =
        (scene.lights.iter()).find(|l| l.mode == LightMode::Realtime && l.layer.is_some())
    {
        return Err(Error::Config {
            key: "layers".into(),
            message: format!(
                "light `{}` (node `{}`) is realtime, so it is not baked, but its node names layer `{}`: remove the layer or bake the light",
                l.name,
                l.node,
                l.layer.as_deref().unwrap_or_default()
            ),
        });
    }
    check_live(scene, config)?;
    let name = |n: &Option<String>| n.clone().unwrap_or_else(|| STATIC_LAYER.to_owned());
    let light: Vec<Option<String>> = (scene.lights.iter())
        .map(|l| match l.mode {
            LightMode::Realtime => None,
            LightMode::Live => Some(LIVE_LAYER.to_owned()),
            _ => Some(name(&l.layer)),
        })
        .collect();
    let material: Vec<Option<String>> = (scene.materials.iter())
        .map(|m| m.is_emissive().then(|| name(&m.layer)))
        .collect();
    let sky = (!sky_black).then(|| name(&config.sky_layer));
    let mut names: Vec<String> = (light.iter().chain(&material).chain([&sky]))
        .flatten()
        .cloned()
        .collect();
    names.sort_by(|a, b| (a != STATIC_LAYER, a).cmp(&(b != STATIC_LAYER, b)));
    names.dedup();
    let index = |n: &Option<String>| n.as_ref().and_then(|n| names.iter().position(|x| x == n));
    Ok(Some(Layers {
        light: light.iter().map(index).collect(),
        material: material.iter().map(index).collect(),
        sky: index(&sky),
        names,
    }))
}

/// The layer [`LIVE_LAYER`] holds the live lights' bounced light and
/// nothing else: the run time replaces its pages.
///
/// # Errors
/// [`Error::Config`] for a live light whose node names another layer, or
/// for anything else in layer `live`.
fn check_live(scene: &Scene, config: &BakeConfig) -> Result<()> {
    let bad = |message: String| {
        Err(Error::Config {
            key: "layers".into(),
            message,
        })
    };
    for l in &scene.lights {
        match (l.mode == LightMode::Live, l.layer.as_deref()) {
            (true, Some(layer)) if layer != LIVE_LAYER => {
                return bad(format!(
                    "light `{}` is live, so its bounced light is in layer `{LIVE_LAYER}`, but its node names layer `{layer}`: remove the layer",
                    l.name
                ))
            }
            (false, Some(LIVE_LAYER)) => {
                return bad(format!(
                    "light `{}` names layer `{LIVE_LAYER}`, which holds only the live lights' bounced light: give it another layer or mode `live`",
                    l.name
                ))
            }
            _ => {}
        }
    }
    let material = scene
        .materials
        .iter()
        .find(|m| m.layer.as_deref() == Some(LIVE_LAYER));
    if let Some(m) = material {
        return bad(format!(
            "material `{}` names layer `{LIVE_LAYER}`, which holds only the live lights' bounced light",
            m.name
        ));
    }
    if config.sky_layer.as_deref() == Some(LIVE_LAYER) {
        return bad(format!(
            "sky_layer `{LIVE_LAYER}`: that layer holds only the live lights' bounced light"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Light, LightKind, Material};
    use glam::Vec3;

    fn scene() -> Scene {
        let lamp = |name: &str, layer: Option<&str>| Light {
            layer: layer.map(str::to_owned),
            ..Light::delta(name, LightKind::Point, Vec3::ONE, Vec3::ZERO, Vec3::NEG_Y)
        };
        Scene {
            lights: vec![
                lamp("a", Some("lamp")),
                lamp("b", None),
                lamp("c", Some("flicker")),
            ],
            materials: vec![
                Material::fallback(),
                Material {
                    emission: Vec3::ONE,
                    layer: Some("ceiling".into()),
                    ..Material::fallback()
                },
            ],
            ..Default::default()
        }
    }

    #[test]
    fn names_static_first_then_alphabetical() {
        let config = BakeConfig {
            sky_layer: Some("sky".into()),
            ..BakeConfig::default()
        };
        let l = resolve(&scene(), &config, false).unwrap().unwrap();
        assert_eq!(l.names, ["static", "ceiling", "flicker", "lamp", "sky"]);
        assert_eq!(l.light, [Some(3), Some(0), Some(2)]);
        assert_eq!(l.material, [None, Some(1)]);
        assert_eq!(l.sky, Some(4));
        let (lights, materials, sky) = l.members(&scene(), 0);
        assert_eq!(
            (lights, materials, sky),
            (vec!["b".to_owned()], vec![], false)
        );
        // A black sky is in no layer.
        let l = resolve(&scene(), &config, true).unwrap().unwrap();
        assert_eq!((l.sky, l.len()), (None, 4));
    }

    #[test]
    fn off_or_unnamed_is_one_bake() {
        let off = BakeConfig {
            layers: LayerMode::Off,
            ..BakeConfig::default()
        };
        assert_eq!(resolve(&scene(), &off, false).unwrap(), None);
        let mut plain = scene();
        plain.lights.iter_mut().for_each(|l| l.layer = None);
        plain.materials[1].layer = None;
        assert_eq!(
            resolve(&plain, &BakeConfig::default(), false).unwrap(),
            None
        );
    }

    #[test]
    fn a_layer_on_a_realtime_light_is_refused() {
        let mut s = scene();
        s.lights[0].mode = LightMode::Realtime;
        let e = resolve(&s, &BakeConfig::default(), false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("light `a`") && e.contains("realtime"), "{e}");
        // A realtime light in no layer is simply not in one.
        s.lights[0].layer = None;
        let l = resolve(&s, &BakeConfig::default(), false).unwrap().unwrap();
        assert_eq!(l.light[0], None);
    }
}

//! Light modes applied to a scene: each light's [`LightMode`] resolved from
//! the settings ([`LightModes`]), its node's `extras.radbake.mode` and the
//! defaults, and checked.

use crate::config::{LightMode, LightModes};
use crate::error::{Error, Result};
use crate::scene::{Light, LightKind, Scene};

impl LightModes {
    /// The mode of `light` (see [`LightModes`]).
    pub fn resolve(&self, light: &Light) -> LightMode {
        let by_type = match light.kind {
            LightKind::Directional => self.directional,
            LightKind::Point => self.point,
            LightKind::Spot { .. } => self.spot,
        };
        self.lights
            .get(&light.name)
            .or_else(|| self.lights.get(&light.node))
            .copied()
            .or(light.node_mode)
            .or(by_type)
            .unwrap_or_default()
    }

    /// Sets every light's [`Light::mode`] in `scene`.
    ///
    /// # Errors
    /// [`Error::Config`] for a name in `lights` that names no light (a
    /// misspelt name would otherwise bake the light in the wrong mode).
    pub fn apply(&self, scene: &mut Scene) -> Result<()> {
        self.check_names(scene)?;
        for light in &mut scene.lights {
            light.mode = self.resolve(light);
        }
        check_live(scene)
    }

    /// Checks that `scene`'s lights have the modes these settings give
    /// them ([`LightModes::apply`] was called).
    ///
    /// # Errors
    /// [`Error::Config`] naming the first light that differs, or a name
    /// that names no light.
    pub fn check(&self, scene: &Scene) -> Result<()> {
        self.check_names(scene)?;
        match scene.lights.iter().find(|l| l.mode != self.resolve(l)) {
            Some(l) => Err(Error::Config {
                key: "light_modes".into(),
                message: format!(
                    "light `{}` is {} in the scene but {} by these settings: call LightModes::apply on the scene before baking",
                    l.name,
                    l.mode.name(),
                    self.resolve(l).name()
                ),
            }),
            None => check_live(scene),
        }
    }

    fn check_names(&self, scene: &Scene) -> Result<()> {
        for name in self.lights.keys() {
            if !scene
                .lights
                .iter()
                .any(|l| &l.name == name || &l.node == name)
            {
                let known: Vec<&str> = scene.lights.iter().map(|l| l.name.as_str()).collect();
                return Err(Error::Config {
                    key: format!("light_modes.lights.{name}"),
                    message: format!(
                        "no light is named `{name}` (the scene's lights: {})",
                        if known.is_empty() {
                            "none".to_owned()
                        } else {
                            known.join(", ")
                        }
                    ),
                });
            }
        }
        Ok(())
    }
}

/// `live` is for directional lights only: the run time re-solves the
/// bounce light for a direction, not for a position.
///
/// # Errors
/// [`Error::Config`] naming the first point or spot light in mode `live`.
fn check_live(scene: &Scene) -> Result<()> {
    match (scene.lights.iter())
        .find(|l| l.mode == LightMode::Live && l.kind != LightKind::Directional)
    {
        Some(l) => Err(Error::Config {
            key: "light_modes".into(),
            message: format!(
                "light `{}` (node `{}`) is a {} light in mode `live`: `live` is for directional lights only",
                l.name,
                l.node,
                match l.kind {
                    LightKind::Point => "point",
                    _ => "spot",
                }
            ),
        }),
        None => Ok(()),
    }
}

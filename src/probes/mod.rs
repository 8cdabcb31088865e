//! Light probes for dynamic objects: regular grids of probes
//! ([`placement`]), each holding the incident radiance over its sphere as L2
//! spherical harmonics ([`light`], [`sh`]); probes inside solids are found
//! by back-face votes and filled from their neighbours ([`fill`]).
//!
//! The probes read the finished lightmap: a probe ray that meets a surface
//! sees its outgoing radiance, albedo × lightmap value (+ emission), so the
//! probes carry every bounce the lightmap does, whatever the transport
//! method. Direct light from punctual lights, sampled emitters and the sky
//! is added at the probe itself.

pub mod fill;
pub mod light;
pub mod placement;
pub mod sh;

use crate::config::BakeConfig;
use crate::light::lights::{sampled_materials, Lights, Mask};
use crate::surface::Surfaces;
use glam::Vec3;
use light::ProbeLight;
pub use placement::{Volume, VolumeSpec};
use rayon::prelude::*;
pub use sh::Sh9;

/// The probes of a bake.
#[derive(Clone, Debug, Default)]
pub struct Probes {
    /// The grids; probe `v.first + i` is probe `i` of grid `v`.
    pub volumes: Vec<Volume>,
    /// Radiance SH per probe (invalid ones filled).
    pub sh: Vec<Sh9>,
    /// False for a probe found inside a solid (its SH is its neighbours').
    pub valid: Vec<bool>,
    /// Factor by which `probe_budget` coarsened the spacing (1: it did not).
    pub coarsened: f32,
    /// The grids are the scene's `probe_volume` nodes (not the automatic
    /// box over the scene).
    pub placed: bool,
    /// Invalid probes that no valid neighbour could fill (left black).
    pub unfilled: usize,
    /// Rays cast.
    pub rays: u64,
    /// Per light layer ([`crate::scene::layers`]; empty without layers),
    /// its share of `sh`: the same rays, validity and fill, so the layers
    /// sum to `sh`.
    pub layers: Vec<Vec<Sh9>>,
}

impl Probes {
    /// Number of probes.
    pub fn len(&self) -> usize {
        self.sh.len()
    }

    /// True without probes.
    pub fn is_empty(&self) -> bool {
        self.sh.is_empty()
    }

    /// Probes found inside solids.
    pub fn invalid(&self) -> usize {
        self.valid.iter().filter(|v| !**v).count()
    }

    /// World position of probe `i`.
    pub fn position(&self, i: usize) -> Vec3 {
        let v = self.volume_of(i);
        v.position(i - v.first)
    }

    /// The grid holding probe `i`.
    pub fn volume_of(&self, i: usize) -> &Volume {
        let k = self.volumes.partition_point(|v| v.first <= i) - 1;
        &self.volumes[k]
    }

    /// Irradiance / π at world point `p` for normal `n`, from the SH of the
    /// grid holding `p` interpolated trilinearly between the eight probes
    /// around it (clamped to the outer probes, as Bevy samples); `None`
    /// outside every grid.
    pub fn irradiance_over_pi(&self, p: Vec3, n: Vec3) -> Option<Vec3> {
        let (v, local) = self
            .volumes
            .iter()
            .map(|v| (v, v.to_local(p)))
            .find(|(_, l)| l.abs().max_element() <= 0.5)?;
        let r = v.resolution.as_vec3();
        let stp = ((local + 0.5) * r).clamp(Vec3::splat(0.5), r - 0.5) - 0.5;
        let base = stp.floor();
        let f = stp - base;
        let mut out = Vec3::ZERO;
        for corner in 0..8u32 {
            let o = glam::UVec3::new(corner & 1, (corner >> 1) & 1, corner >> 2);
            let c = (base.as_uvec3() + o).min(v.resolution - 1);
            let w = Vec3::select(o.cmpeq(glam::UVec3::ONE), f, 1.0 - f);
            let i = v.first + v.index(c);
            out += sh::irradiance_over_pi(&self.sh[i], n) * (w.x * w.y * w.z);
        }
        Some(out)
    }
}

impl Probes {
    /// Reads the probes a bake wrote (`probes.json` and the binary it
    /// names, see [`crate::output::probes`]).
    ///
    /// # Errors
    /// A one-line message naming the file and the problem.
    pub fn read(json_path: &std::path::Path) -> crate::Result<Probes> {
        use crate::Error;
        let io = |path: &std::path::Path| {
            let path = path.to_path_buf();
            move |source| Error::Io { path, source }
        };
        let bad = |message: String| Error::Malformed {
            path: json_path.to_path_buf(),
            message,
        };
        let text = std::fs::read(json_path).map_err(io(json_path))?;
        let json: serde_json::Value =
            serde_json::from_slice(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
        let count = json["probes"]
            .as_u64()
            .ok_or_else(|| bad("no probe count".into()))? as usize;
        let bin_name = json["binary"].as_str().unwrap_or("probes.bin");
        let bin_path = json_path.with_file_name(bin_name);
        let bin = std::fs::read(&bin_path).map_err(io(&bin_path))?;
        if bin.len() != count * 27 * 4 {
            return Err(Error::Malformed {
                path: bin_path.clone(),
                message: format!(
                    "{} bytes, but {} says {count} probes ({} bytes)",
                    bin.len(),
                    json_path.display(),
                    count * 108
                ),
            });
        }
        let f: Vec<f32> = bin
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let sh: Vec<Sh9> = f
            .chunks_exact(27)
            .map(|c| std::array::from_fn(|k| Vec3::new(c[3 * k], c[3 * k + 1], c[3 * k + 2])))
            .collect();
        let mut valid = vec![true; count];
        for i in json["invalid_probes"].as_array().into_iter().flatten() {
            match i.as_u64() {
                Some(i) if (i as usize) < count => valid[i as usize] = false,
                _ => return Err(bad(format!("invalid_probes holds {i}, not a probe index"))),
            }
        }
        let mut volumes = Vec::new();
        for (k, v) in json["volumes"].as_array().into_iter().flatten().enumerate() {
            let malformed = || bad(format!("volumes[{k}] is malformed"));
            let m: Vec<f32> = v["world_from_box"]
                .as_array()
                .ok_or_else(malformed)?
                .iter()
                .map(|x| x.as_f64().map(|x| x as f32))
                .collect::<Option<_>>()
                .ok_or_else(malformed)?;
            let r: Vec<u32> = v["resolution"]
                .as_array()
                .ok_or_else(malformed)?
                .iter()
                .map(|x| x.as_u64().map(|x| x as u32))
                .collect::<Option<_>>()
                .ok_or_else(malformed)?;
            if m.len() != 16 || r.len() != 3 || r.contains(&0) {
                return Err(malformed());
            }
            let vol = Volume {
                name: v["name"].as_str().unwrap_or("").to_owned(),
                world_from_box: glam::Mat4::from_cols_slice(&m),
                resolution: glam::UVec3::new(r[0], r[1], r[2]),
                first: v["first_probe"].as_u64().ok_or_else(malformed)? as usize,
            };
            if vol.first + vol.len() > count {
                return Err(bad(format!("volumes[{k}] runs past the {count} probes")));
            }
            volumes.push(vol);
        }
        Ok(Probes {
            volumes,
            sh,
            valid,
            coarsened: 1.0,
            placed: false,
            unfilled: json["unfilled_probes"].as_u64().unwrap_or(0) as usize,
            layers: Vec::new(),
            rays: 0,
        })
    }
}

/// What the probe stage needs from the bake.
pub struct Inputs<'a> {
    /// The surfaces.
    pub s: &'a Surfaces<'a>,
    /// The lightmap value (incident irradiance / π) per texel, filled.
    pub texel_values: &'a [Vec3],
    /// The mixed lights' direct light per texel (irradiance / π; may be
    /// empty), which the lightmap leaves out but the surfaces reflect.
    pub mixed: &'a [Vec3],
    /// What rays leaving the scene see.
    pub sky: &'a crate::light::sky::Sky,
    /// The boxes the scene places (empty: one box over the scene).
    pub specs: &'a [VolumeSpec],
}

/// A light layer's inputs to the probes ([`bake_layers`]).
pub struct LayerInputs<'a> {
    /// The layer's lightmap value per texel, filled.
    pub texel_values: &'a [Vec3],
    /// The layer's mixed lights' direct light per texel (may be empty).
    pub mixed: &'a [Vec3],
    /// The layer's share of each light.
    pub mask: Mask,
}

/// Bakes the probes (see the module doc). `advance` is called with probes
/// done.
pub fn bake(inputs: &Inputs, config: &BakeConfig, advance: &(dyn Fn(u64) + Sync)) -> Probes {
    bake_layers(inputs, &[], config, advance)
}

/// [`bake`], and each light layer's SH ([`Probes::layers`]) in the same
/// pass: the whole's rays read for every layer
/// ([`light::ProbeLight::probe_layers`]), filled with the whole's
/// validity. Each layer's SH is what [`bake`] over the layer's inputs
/// gives.
pub fn bake_layers(
    inputs: &Inputs,
    layers: &[LayerInputs],
    config: &BakeConfig,
    advance: &(dyn Fn(u64) + Sync),
) -> Probes {
    let s = inputs.s;
    let g = s.geometry;
    let bounds = g.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    let (volumes, coarsened) = placement::place(
        bounds,
        inputs.specs,
        config.probe_spacing,
        config.probe_budget,
    );
    let sampled = sampled_materials(s.scene, g, config.emitters);
    let mut lights = Lights::new(s.scene, g, &sampled, inputs.sky.clone());
    lights.sky_samples = config.sky_samples;
    // What the surfaces reflect: the lightmap, plus the mixed lights'
    // direct light, which the lightmap leaves to the engine.
    let radiance_of = |values: &[Vec3], mixed: &[Vec3]| -> Vec<Vec3> {
        (s.texels.albedo.iter().zip(values).enumerate())
            .map(|(t, (a, v))| *a * (*v + mixed.get(t).copied().unwrap_or_default()))
            .collect()
    };
    let radiance = radiance_of(inputs.texel_values, inputs.mixed);
    let layer_lights: Vec<Lights> = layers.iter().map(|l| lights.masked(l.mask.clone())).collect();
    let layer_probes: Vec<light::LayerProbe> = (layers.iter().zip(&layer_lights))
        .map(|(l, lights)| light::LayerProbe {
            radiance: radiance_of(l.texel_values, l.mixed),
            lights,
        })
        .collect();
    let pl = ProbeLight {
        s,
        radiance,
        sampled: &sampled,
        lights: &lights,
        rays: config.probe_rays,
        light_samples: config.direct_samples.min(config.probe_rays),
        seed: config.seed,
    };
    let positions: Vec<Vec3> = volumes
        .iter()
        .flat_map(|v| (0..v.len()).map(move |i| v.position(i)))
        .collect();
    let chunk = 64;
    let k = layers.len();
    let samples: Vec<(light::ProbeSample, Vec<Sh9>)> = positions
        .par_chunks(chunk)
        .enumerate()
        .flat_map_iter(|(c, ps)| {
            let out: Vec<_> = ps
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let mut ls = vec![[Vec3::ZERO; 9]; k];
                    (pl.probe_layers(c * chunk + i, *p, &layer_probes, &mut ls), ls)
                })
                .collect();
            advance(out.len() as u64);
            out
        })
        .collect();
    let mut sh: Vec<Sh9> = samples.iter().map(|x| x.0.sh).collect();
    let valid: Vec<bool> = samples.iter().map(|x| x.0.valid).collect();
    let rays = samples.iter().map(|x| x.0.rays as u64).sum();
    let mut layer_sh: Vec<Vec<Sh9>> = (0..k)
        .map(|i| samples.iter().map(|x| x.1[i]).collect())
        .collect();
    drop(samples);
    let mut unfilled = 0;
    for v in &volumes {
        let range = v.first..v.first + v.len();
        unfilled += fill::fill(v, &mut sh[range.clone()], &valid[range.clone()]);
        for l in &mut layer_sh {
            fill::fill(v, &mut l[range.clone()], &valid[range.clone()]);
        }
    }
    Probes {
        volumes,
        sh,
        valid,
        coarsened,
        placed: !inputs.specs.is_empty(),
        unfilled,
        rays,
        layers: layer_sh,
    }
}

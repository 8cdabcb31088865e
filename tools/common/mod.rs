//! What the measuring examples share: a scene named on the command line
//! and bake settings given as `KEY=VALUE` pairs, as in a `--config` TOML
//! file (e.g. `texels_per_meter=4 'sky=[0.4,0.5,0.7]'`).

use radbake::scene::Scene;
use radbake::BakeConfig;

/// `SCENE [KEY=VALUE ...]` from the command line: the loaded scene and the
/// default settings with the pairs (and then `extra`, TOML lines) laid
/// over them. `name` is the example's, for the usage line.
pub fn scene_and_settings(name: &str, extra: &str) -> anyhow::Result<(Scene, BakeConfig)> {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .ok_or_else(|| anyhow::anyhow!("usage: {name} SCENE [KEY=VALUE ...]"))?;
    let toml: String = args.map(|a| a + "\n").collect::<String>() + extra;
    let config = BakeConfig::from_toml_over(&BakeConfig::default(), &toml)?;
    let scene = radbake::scene::load(std::path::Path::new(&path), &Default::default())?;
    Ok((scene, config))
}

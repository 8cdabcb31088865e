//! intel_tex_2's prebuilt ISPC kernels (BC6H pages) reference the C++
//! runtime's exception personality (`__gxx_personality_v0`): link it.
fn main() {
    // Without this line Cargo reruns the script, and so rebuilds the
    // library, whenever any file of the package changes (an example, a
    // test): a minute of every edit-and-run on two cores.
    println!("cargo:rerun-if-changed=build.rs");
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    let env = std::env::var("CARGO_CFG_TARGET_ENV").unwrap_or_default();
    match (os.as_str(), env.as_str()) {
        ("macos" | "ios" | "freebsd", _) => println!("cargo:rustc-link-lib=dylib=c++"),
        (_, "msvc") => {}
        _ => println!("cargo:rustc-link-lib=dylib=stdc++"),
    }
}

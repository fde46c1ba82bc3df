// intel_tex_2 links prebuilt ISPC/C++ objects that need the C++ runtime.
fn main() {
    let target = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    if target == "linux" {
        println!("cargo:rustc-link-lib=dylib=stdc++");
    }
}

//! With the `oidn` feature, the binary and its tests find Open Image Denoise in the folder
//! `OIDN_DIR` names (see `tools/setup-oidn.sh`) by their run path, so no `LD_LIBRARY_PATH`
//! is needed.

fn main() {
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    if std::env::var_os("CARGO_FEATURE_OIDN").is_some() {
        if let Some(dir) = std::env::var_os("OIDN_DIR") {
            println!("cargo:rustc-link-arg=-Wl,-rpath,{}/lib", dir.to_string_lossy());
        }
    }
}

//! Compiles `proto/palpa.proto` for the `record` feature with protox (no `protoc` needed): Rust types
//! by prost, and the FileDescriptorSet bytes that recordings embed as their schemas.

fn main() {
    println!("cargo:rerun-if-changed=proto/palpa.proto");
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var_os("CARGO_FEATURE_RECORD").is_none() {
        return;
    }
    let descriptors =
        protox::compile(["proto/palpa.proto"], ["proto"]).expect("proto/palpa.proto compiles");
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    let bytes = prost::Message::encode_to_vec(&descriptors);
    std::fs::write(out.join("palpa_descriptor_set.bin"), bytes).expect("write the descriptor set");
    prost_build::Config::new()
        .compile_fds(descriptors)
        .expect("generate the Rust types");
}

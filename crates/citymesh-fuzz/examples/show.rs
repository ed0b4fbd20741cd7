//! Prints the building a saved `building-NNN.bin` describes: `cargo run -p citymesh-fuzz --example show FILE`.
#![allow(clippy::unwrap_used, clippy::print_stdout)]
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let bytes = std::fs::read(path).unwrap();
    println!("{:#?}", citymesh_fuzz::decode_building(&bytes));
}

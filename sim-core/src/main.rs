fn main() {
    eprintln!("sim-core: not built yet");
    std::process::exit(2);
}

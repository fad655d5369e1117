fn main() {
    eprintln!("world-server: not built yet");
    std::process::exit(2);
}

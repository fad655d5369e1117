fn main() {
    eprintln!("cosim: not built yet");
    std::process::exit(2);
}

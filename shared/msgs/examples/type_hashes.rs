//! Prints the RIHS01 hash of every message type: `cargo run -p teleop-msgs --example type_hashes`.
fn main() {
    for (d, declared) in teleop_msgs::all_descriptions() {
        let computed = d.type_hash();
        let mark = if computed == declared {
            "ok"
        } else {
            "MISMATCH"
        };
        println!("{:40} {computed} {mark}", d.type_name);
    }
}

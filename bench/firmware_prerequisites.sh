# Sourced by the scripts that build and run the firmware (bench/target.sh,
# bench/mavlink_link.sh): adds the flight controller's Rust target when it is missing, and stops
# with exit status 2 when QEMU or Python is not installed.
target=thumbv7em-none-eabihf

if ! rustup target list --installed | grep -qx "$target"; then
    echo "adding the Rust target $target" >&2
    rustup target add "$target"
fi
for tool in qemu-system-arm python3; do
    if ! command -v "$tool" >/dev/null; then
        echo "error: $tool is required (Debian: apt-get install qemu-system-arm python3)" >&2
        exit 2
    fi
done

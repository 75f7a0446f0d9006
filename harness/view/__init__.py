"""The scene live in a browser: the FMUs built to WebAssembly, one self-contained page."""

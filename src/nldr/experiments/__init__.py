"""The paper's experiments as library functions: arrays in, tidy pandas frames out (no file I/O)."""

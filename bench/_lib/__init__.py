"""What the benchmark entry scripts share: scenes and problems, the independent re-check,
the peer models, MPlib's venv and runner, the JSON line, the bare Zenoh floors."""

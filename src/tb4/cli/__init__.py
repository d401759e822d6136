"""The `tb4` command line."""

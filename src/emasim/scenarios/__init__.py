"""The paper's experiments as TOML files, and the validated schema that reads them."""

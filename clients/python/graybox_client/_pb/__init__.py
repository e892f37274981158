"""Generated at build time from proto/graybox/v1/*.proto (see setup.py); not committed."""

"""What a run is measured by: metrics, the trusted reference, growth laws, observed orders, linear stability."""

"""Coffee: twist the pot, heat it on the plate, pour into every cup (paper App. A.4)."""

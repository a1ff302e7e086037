"""Cover: put blocks over target pads on a line across the table (paper App. A.1)."""

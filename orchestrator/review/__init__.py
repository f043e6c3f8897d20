"""Reading run logs back: the review summary and figures, compare, and replay."""

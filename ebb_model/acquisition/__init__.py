"""What a data acquisition does to a channel: the band-limited force between samples, the anti-alias filter, a
sigma-delta converter's delay."""

"""Files in and out: the readers of people's and instruments' text, the writers of JSON, TOML, HTML pages and figures,
and the output places every command checks before it works."""

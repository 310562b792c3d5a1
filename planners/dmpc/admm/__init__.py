"""Cooperative formation DMPC solved by ADMM across neighbours (Stomberg et al.): OCP, local QPs, exchange, config."""

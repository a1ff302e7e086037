def register_gymnasium_envs() -> None: pass

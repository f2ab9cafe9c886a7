"""along_route_localization's Python package: the code the command-line scripts in scripts/ share
(script_support). The package's messages and services (along_route_localization.msg, .srv) and its
dynamic_reconfigure configurations (.cfg) are generated into it by the build."""

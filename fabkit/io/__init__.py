"""What comes in and what goes out.

``templates`` is the only reader of template files; ``schema`` declares every setting a user can
give (templates, ``--set``, the API's keywords); ``inputs`` reads the files fabkit did not write
itself, regular and bounded; ``outputs`` guards every path fabkit writes and writes sets of files
all-or-nothing; ``workload`` estimates time and memory before work; ``suggest`` offers the nearest
valid names for a misspelt one.
"""

// The source of the precompiled-header targets (cmake/EvpipeFlags.cmake): the header is the product.

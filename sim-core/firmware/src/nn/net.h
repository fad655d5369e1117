/*
 * The network's generated weights.h (training/export.py): the committed
 * network's (src/nn/weights.h), or another's, chosen at build time with
 * -DNN_WEIGHTS='"sep/weights.h"' (the Makefile's nn_eval_sep: the
 * depthwise-separable network of docs/NN.md).
 */
#ifndef NN_NET_H
#define NN_NET_H

#ifdef NN_WEIGHTS
#include NN_WEIGHTS
#else
#include "weights.h"
#endif

#endif

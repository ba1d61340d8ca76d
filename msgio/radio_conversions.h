#ifndef ROOMFIX_MSGIO_RADIO_CONVERSIONS_H_
#define ROOMFIX_MSGIO_RADIO_CONVERSIONS_H_

#include "core/radio/range_assembler.h"
#include "roomfix/range_set_t.hpp"

namespace roomfix {

// An assembled firing as the range_set_t published on RANGES: utime is the
// firing time, every range carries its receiver's position so that a log
// replays with no site file.
range_set_t RangeSetFromAssembled(const radio::AssembledSet& set);

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_RADIO_CONVERSIONS_H_

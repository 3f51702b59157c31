// What a farm job reads before it renders anything, checked up front: the views file, that every
// subject of it is an object of the store, and the store's identity for the settings hash.
// Errors: false with a message naming the file, the view and the id.
#pragma once

#include <string>
#include <vector>

#include "plantview/camera.h"
#include "plantview/review.h"

namespace plantview {
class ReadView;
}

namespace plantview::cli::farm {

// Reads and parses a views file (review.h: parse_review_views); `text` gets its bytes.
bool read_views_file(const std::string& path, std::vector<ReviewView>& views, std::string& text,
                     std::string& error);

// False naming up to five subject ids that are not objects of the store ("view 'P-101A': id 77").
bool check_subjects(const std::vector<ReviewView>& views, const ReadView& read, std::string& error);

// The store's content as far as images go, as 16 hex digits: a hash of its commit id (which
// changes with every import: StoreInfo::commit_id) and its statistics. A store made before
// commit ids has id 0: only its statistics tell (an import that kept every count and the
// bounds needs --force there).
std::string store_identity(const ReadView& read);

}  // namespace plantview::cli::farm
